# Run by `cmake --install` (install(SCRIPT) in daemon/CMakeLists.txt): writes the systemd units
# and the sample configuration with the install directories of THIS install, so that
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
