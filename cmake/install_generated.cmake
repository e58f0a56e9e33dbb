# Run by `cmake --install` (install(CODE) in cli/CMakeLists.txt) before the man pages and the
# completion are installed: any of them the build did not make (a build of named targets only,
# as scripts/demo's `fogbenchd fogctl fogbench-sim`, leaves out `all`'s fogbench_docs) is made
# now from the built executable, as the build would have, so that a component is complete
# whatever was built. A missing executable is an error naming it, never a silent gap.
# In: FOGBENCH_GENERATED, a list of OUT|EXE|KIND (KIND: man1, man8, mancommands1, bash, zsh),
#     FOGBENCH_MANPAGE (cmake/manpage.cmake), FOGBENCH_SUMMARY_<name> for each page's NAME line.
foreach(entry IN LISTS FOGBENCH_GENERATED)
  string(REPLACE "|" ";" entry "${entry}")
  list(GET entry 0 out)
  list(GET entry 1 exe)
  list(GET entry 2 kind)
  if(EXISTS "${out}")
    continue()
  endif()
  if(NOT EXISTS "${exe}")
    message(FATAL_ERROR "cannot make ${out}: ${exe} is not built (build it, e.g. scripts/build, then install again)")
  endif()
  get_filename_component(name "${exe}" NAME)
  message(STATUS "Generating: ${out} (the build made only named targets)")
  # Written under a temporary name and renamed: two installs at once never read half a file.
  set(tmp "${out}.install-${name}.tmp")
  if(kind STREQUAL "bash" OR kind STREQUAL "zsh")
    execute_process(COMMAND "${exe}" __generate ${kind} OUTPUT_FILE "${tmp}" RESULT_VARIABLE rc ERROR_VARIABLE err)
  else()
    string(REGEX MATCH "[0-9]$" section "${kind}")
    set(commands OFF)
    if(kind MATCHES "^mancommands")
      set(commands ON)
    endif()
    execute_process(COMMAND "${CMAKE_COMMAND}" "-DEXE=${exe}" "-DNAME=${name}" "-DSECTION=${section}"
                            "-DSUMMARY=${FOGBENCH_SUMMARY_${name}}" "-DCOMMANDS=${commands}" "-DOUT=${tmp}"
                            -P "${FOGBENCH_MANPAGE}"
                    RESULT_VARIABLE rc ERROR_VARIABLE err)
  endif()
  if(NOT rc EQUAL 0)
    file(REMOVE "${tmp}")
    message(FATAL_ERROR "cannot make ${out} from ${exe} (${rc}): ${err}")
  endif()
  file(RENAME "${tmp}" "${out}")
endforeach()
