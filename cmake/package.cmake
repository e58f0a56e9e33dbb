# Installs fogbench's libraries, their public headers and the CMake package
# (fogbenchConfig.cmake, fogbenchTargets.cmake), so that another project can
#   find_package(fogbench REQUIRED)
#   target_link_libraries(app PRIVATE fogbench::model)
# tests/package/ builds such a project against an installed tree.
include(CMakePackageConfigHelpers)

set(fogbench_package_libs)
foreach(lib model profiles plans protocol storage sim drivers_protocol drivers)
  if(TARGET fogbench_${lib})
    list(APPEND fogbench_package_libs fogbench_${lib})
    # fogbench_model is exported as fogbench::model.
    set_target_properties(fogbench_${lib} PROPERTIES EXPORT_NAME ${lib})
  endif()
endforeach()
foreach(dir model profiles plans protocol storage sim drivers)
  if(IS_DIRECTORY ${PROJECT_SOURCE_DIR}/${dir}/include)
    install(DIRECTORY ${PROJECT_SOURCE_DIR}/${dir}/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
            COMPONENT dev FILES_MATCHING PATTERN "*.hpp" PATTERN "*.h")
  endif()
endforeach()

set(fogbench_cmake_dir ${CMAKE_INSTALL_LIBDIR}/cmake/fogbench)
install(TARGETS ${fogbench_package_libs} EXPORT fogbenchTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT fogbenchTargets NAMESPACE fogbench:: DESTINATION ${fogbench_cmake_dir} COMPONENT dev)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/fogbenchConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/fogbenchConfig.cmake INSTALL_DESTINATION ${fogbench_cmake_dir})
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/fogbenchConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/fogbenchConfig.cmake ${CMAKE_CURRENT_BINARY_DIR}/fogbenchConfigVersion.cmake
        DESTINATION ${fogbench_cmake_dir} COMPONENT dev)
