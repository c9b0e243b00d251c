# What `cmake --install build [--prefix P]` puts where, the CMake package that
# find_package(omnipose) reads, and the Debian package `cpack -G DEB` makes (run in build/).
#
#   bin/                         the programs
#   include/omnipose/            the public API (+ calibrate/ and lcm/ for the components)
#   lib/                         the static libraries
#   lib/cmake/omnipose/          omniposeConfig.cmake: omnipose::omnipose (calibration, unwrap,
#                                registration, fit, chain, pipeline), omnipose::io,
#                                omnipose::synth, omnipose::eval, omnipose::calibrate,
#                                omnipose::lcm_types
#   lib/systemd/system/          omniposed.service, with the installed path of omniposed
#   share/omnipose/lcm_types/    the LCM type definitions
#   share/doc/omnipose/          DESIGN.md, README.md, LICENSE, daemon.example.yaml
include(CMakePackageConfigHelpers)

set(OMNIPOSE_PROGRAMS omniposed omnipose-replay omnipose-synth omnipose-eval omnipose-calibrate
    omnipose-listen omnipose-plot-fit omnipose-plot-angles omnipose-results)
install(TARGETS ${OMNIPOSE_PROGRAMS} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT runtime)

install(TARGETS omnipose omnipose_io omnipose_synth omnipose_eval omnipose_calibrate
                omnipose_lcm_types EXPORT omniposeTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY ${CMAKE_SOURCE_DIR}/include/omnipose DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        COMPONENT dev)
install(DIRECTORY ${CMAKE_SOURCE_DIR}/src/calibrate/include/omnipose/calibrate
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/omnipose COMPONENT dev)
install(EXPORT omniposeTargets NAMESPACE omnipose:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/omnipose
        COMPONENT dev)
configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/omniposeConfig.cmake.in
  ${CMAKE_BINARY_DIR}/omniposeConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/omnipose)
write_basic_package_version_file(${CMAKE_BINARY_DIR}/omniposeConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/omniposeConfig.cmake ${CMAKE_BINARY_DIR}/omniposeConfigVersion.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/omnipose COMPONENT dev)

# The unit names the installed omniposed: configured at install time, so that `--prefix P`
# and the .deb (prefix /usr) each get their own path. Under the prefix /usr (the .deb) it goes
# to /lib/systemd/system, where Debian keeps package units; elsewhere to P/lib/systemd/system.
install(CODE "
  set(OMNIPOSE_INSTALL_BINDIR \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_BINDIR}\")
  set(OMNIPOSE_INSTALL_DOCDIR \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_DOCDIR}\")
  configure_file(\"${CMAKE_SOURCE_DIR}/tools/omniposed.service.in\"
                 \"${CMAKE_BINARY_DIR}/omniposed.service\" @ONLY)
  if(CMAKE_INSTALL_PREFIX STREQUAL \"/usr\")
    set(unit_dir \"/lib/systemd/system\")
  else()
    set(unit_dir \"\${CMAKE_INSTALL_PREFIX}/lib/systemd/system\")
  endif()
  file(INSTALL \"${CMAKE_BINARY_DIR}/omniposed.service\" DESTINATION \"\${unit_dir}\")
" COMPONENT runtime)
install(FILES ${CMAKE_SOURCE_DIR}/docs/DESIGN.md ${CMAKE_SOURCE_DIR}/README.md
              ${CMAKE_SOURCE_DIR}/LICENSE ${CMAKE_SOURCE_DIR}/tools/omniposed/daemon.example.yaml
        DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT runtime)

# cpack -G DEB: one package, its dependencies from the shared-library scan (dpkg-shlibdeps).
set(CPACK_PACKAGE_NAME omnipose)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "Pose of an omni-directional camera from sinusoid fitting of iFMI motions (daemon, tools, library)")
set(CPACK_PACKAGE_CONTACT "omnipose maintainers <omnipose@localhost>")
set(CPACK_RESOURCE_FILE_LICENSE ${CMAKE_SOURCE_DIR}/LICENSE)
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "")
include(CPack)
