# Run by `cmake --install` (install(CODE) in daemon/CMakeLists.txt): writes the systemd units
# and the sample configuration (and etc/fogbench/fogbenchd.json from it when there is none)
# with the install directories of THIS install, so that
# `cmake --install build --prefix /opt/x` gets units that run /opt/x/sbin/fogbenchd. The
# directories are the GNUInstallDirs ones (relative to the prefix unless absolute), with its
# rule that a /usr prefix keeps its configuration in /etc.
# In: FOGBENCH_SOURCE_DIR, FOGBENCH_SBINDIR, FOGBENCH_SYSCONFDIR, FOGBENCH_DATADIR,
#     FOGBENCH_DOCDIR, FOGBENCH_UNITDIR (all as configured, usually relative).
function(fogbench_full dir out)
  if(IS_ABSOLUTE "${dir}")
    set(${out} "${dir}" PARENT_SCOPE)
  elseif(dir STREQUAL "etc" AND (CMAKE_INSTALL_PREFIX STREQUAL "/usr" OR CMAKE_INSTALL_PREFIX STREQUAL "/"))
    set(${out} "/etc" PARENT_SCOPE)
  else()
    set(${out} "${CMAKE_INSTALL_PREFIX}/${dir}" PARENT_SCOPE)
  endif()
endfunction()

fogbench_full("${FOGBENCH_SBINDIR}" CMAKE_INSTALL_FULL_SBINDIR)
fogbench_full("${FOGBENCH_SYSCONFDIR}" CMAKE_INSTALL_FULL_SYSCONFDIR)
fogbench_full("${FOGBENCH_DATADIR}" CMAKE_INSTALL_FULL_DATADIR)
fogbench_full("${FOGBENCH_DOCDIR}" CMAKE_INSTALL_FULL_DOCDIR)
fogbench_full("${FOGBENCH_UNITDIR}" unitdir)

foreach(pair "fogbenchd.service;${unitdir}" "fogbenchd@.service;${unitdir}" "fogbenchd.json.example;${CMAKE_INSTALL_FULL_DOCDIR}")
  list(GET pair 0 name)
  list(GET pair 1 dest)
  set(target "$ENV{DESTDIR}${dest}/${name}")
  message(STATUS "Installing: ${target}")
  configure_file("${FOGBENCH_SOURCE_DIR}/systemd/${name}.in" "${target}" @ONLY)
  list(APPEND CMAKE_INSTALL_MANIFEST_FILES "${target}")
endforeach()

# The configuration the units start from (<sysconf>/fogbench/fogbenchd.json): the sample, when
# there is none. One that exists is the station's and is never replaced, whatever its contents;
# the install says so and where the new sample is (share/doc/fogbench/fogbenchd.json.example).
# A kept file is left out of the manifest, so that removing the install leaves it too.
set(config "$ENV{DESTDIR}${CMAKE_INSTALL_FULL_SYSCONFDIR}/fogbench/fogbenchd.json")
if(EXISTS "${config}" OR IS_SYMLINK "${config}")
  message(STATUS "Keeping: ${config} (it exists: never overwritten; the new sample is "
                 "${CMAKE_INSTALL_FULL_DOCDIR}/fogbenchd.json.example)")
else()
  message(STATUS "Installing: ${config} (the sample configuration: edit its drivers for this bench)")
  configure_file("${FOGBENCH_SOURCE_DIR}/systemd/fogbenchd.json.example.in" "${config}" @ONLY)
  list(APPEND CMAKE_INSTALL_MANIFEST_FILES "${config}")
endif()
