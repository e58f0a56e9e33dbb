# A man page from an executable's --help, at build time (cmake -P): the help text as written, in
# roff, so the page never disagrees with the program. With COMMANDS set, `EXE __generate
# commands` lists the subcommands and each one's --help follows in a section of its own.
#   cmake -DEXE=path -DNAME=fogctl -DSECTION=1 -DSUMMARY="..." [-DCOMMANDS=ON] -DOUT=fogctl.1 -P manpage.cmake
function(roff_escape text out)
  string(REPLACE "\\" "\\e" text "${text}")
  # A line starting with '.' or '\'' is a roff request: guard it.
  string(REGEX REPLACE "\n([.'])" "\n\\\\&\\1" text "${text}")
  set(${out} "${text}" PARENT_SCOPE)
endfunction()

function(help_of args out)
  execute_process(COMMAND ${EXE} ${args} --help OUTPUT_VARIABLE text RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${EXE} ${args} --help failed (${rc}): ${err}")
  endif()
  # CLI11 prints argv[0], the build tree's path: the page names the command.
  string(REPLACE "${EXE}" "${NAME}" text "${text}")
  roff_escape("${text}" text)
  set(${out} "${text}" PARENT_SCOPE)
endfunction()

execute_process(COMMAND ${EXE} --version OUTPUT_VARIABLE version OUTPUT_STRIP_TRAILING_WHITESPACE)
string(TOUPPER "${NAME}" upper)
help_of("" main)
set(page ".TH ${upper} ${SECTION} \"\" \"fogbench ${version}\" \"fogbench\"\n.SH NAME\n${NAME} \\- ${SUMMARY}\n")
string(APPEND page ".SH SYNOPSIS\n.nf\n${main}.fi\n")
if(COMMANDS)
  execute_process(COMMAND ${EXE} __generate commands OUTPUT_VARIABLE cmds RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${EXE} __generate commands failed")
  endif()
  string(APPEND page ".SH COMMANDS\n")
  string(REPLACE "\n" ";" cmds "${cmds}")
  foreach(cmd IN LISTS cmds)
    if(cmd STREQUAL "")
      continue()
    endif()
    string(REPLACE " " ";" args "${cmd}")
    help_of("${args}" text)
    string(APPEND page ".SS ${NAME} ${cmd}\n.nf\n${text}.fi\n")
  endforeach()
endif()
# Each file named here is installed in share/doc/fogbench (cli/CMakeLists.txt, daemon/CMakeLists.txt;
# tests/package/install_layout.sh checks every name against the installed folder).
string(APPEND page ".SH SEE ALSO\nThe documentation installed with fogbench in share/doc/fogbench under the install prefix: "
                   "cli.md, daemon.md, storage.md, csv.md, protocol.md, web.md and the sample configuration "
                   "fogbenchd.json.example; mock-bench.md with the mock bench (component mockbench).\n")
file(WRITE ${OUT} "${page}")
