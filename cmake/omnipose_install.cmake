# What `cmake --install build [--prefix P]` puts where, the CMake package that
# find_package(omnipose) reads, and the two Debian packages `cpack -G DEB` makes (run in build/).
# LIBDIR is lib/<multiarch triplet> (lib/x86_64-linux-gnu) on Debian, see below.
#
#   package omnipose (COMPONENT runtime):
#   bin/                             the programs
#   lib/systemd/system/              omniposed.service, with the installed path of omniposed
#   share/doc/omnipose/              DESIGN.md, README.md, CHANGELOG.md, LICENSE,
#                                    daemon.example.yaml
#   lib/python3/dist-packages/omnipose/   the LCM types for Python (lcm_types/CMakeLists.txt)
#   share/java/omnipose_lcm_types.jar     the LCM types for Java, lcm-spy (when built)
#
#   package libomnipose-dev (COMPONENT dev):
#   include/omnipose/                the public API: the core's headers, and a folder per
#                                    component (io/, synth/, eval/, calibrate/, lcm/)
#   LIBDIR/                          the static libraries
#   LIBDIR/cmake/omnipose/           omniposeConfig.cmake: omnipose::omnipose (calibration, unwrap,
#                                    registration, fit, chain, pipeline), omnipose::io,
#                                    omnipose::synth, omnipose::eval, omnipose::calibrate,
#                                    omnipose::lcm_types
#   share/omnipose/lcm_types/        the LCM type definitions
#
# libomnipose-dev does not depend on omnipose: the libraries, headers and CMake package use
# nothing of the programs, the unit or the Python/Java types.
include(CMakePackageConfigHelpers)

# Multiarch: Debian's GNUInstallDirs gives LIBDIR = lib/<triplet> only for the prefix /usr,
# but the .deb is packed (prefix /usr) from a build configured for any prefix, and the paths
# are fixed at configure time. So on a multiarch system the libraries go to lib/<triplet>
# under every prefix; find_package searches <prefix>/lib/<triplet>/cmake as well.
# -DOMNIPOSE_INSTALL_MULTIARCH=OFF keeps CMAKE_INSTALL_LIBDIR as GNUInstallDirs set it.
option(OMNIPOSE_INSTALL_MULTIARCH
       "Install the libraries and the CMake package under lib/<multiarch triplet>" ON)
if(OMNIPOSE_INSTALL_MULTIARCH AND CMAKE_LIBRARY_ARCHITECTURE AND CMAKE_INSTALL_LIBDIR STREQUAL "lib")
  set(CMAKE_INSTALL_LIBDIR lib/${CMAKE_LIBRARY_ARCHITECTURE})
endif()
message(STATUS "omnipose: libraries and CMake package install to <prefix>/${CMAKE_INSTALL_LIBDIR}")
# For the install tests (tests/install), configured before this file is read.
file(CONFIGURE OUTPUT ${CMAKE_BINARY_DIR}/omnipose_install_dirs.cmake CONTENT
     "set(OMNIPOSE_INSTALL_LIBDIR \"${CMAKE_INSTALL_LIBDIR}\")\n")

set(OMNIPOSE_PROGRAMS omniposed omnipose-replay omnipose-synth omnipose-eval omnipose-calibrate
    omnipose-listen omnipose-plot-fit omnipose-plot-angles omnipose-results omnipose-equirect
    omnipose-plot-uncertainty)
install(TARGETS ${OMNIPOSE_PROGRAMS} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT runtime)

install(TARGETS omnipose omnipose_io omnipose_synth omnipose_eval omnipose_calibrate
                omnipose_lcm_types EXPORT omniposeTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
# include/omnipose as in the source tree: the core's headers and io/, synth/, eval/,
# calibrate/; not baselines/ (the feature-based baselines are built for evaluation only).
install(DIRECTORY ${CMAKE_SOURCE_DIR}/include/omnipose DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        COMPONENT dev PATTERN baselines EXCLUDE)
install(EXPORT omniposeTargets NAMESPACE omnipose:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/omnipose
        COMPONENT dev)
set(OMNIPOSE_INSTALL_LCM_TYPES_DIR ${CMAKE_INSTALL_DATADIR}/omnipose/lcm_types)
configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/omniposeConfig.cmake.in
  ${CMAKE_BINARY_DIR}/omniposeConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/omnipose
  PATH_VARS OMNIPOSE_INSTALL_LCM_TYPES_DIR)
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
              ${CMAKE_SOURCE_DIR}/CHANGELOG.md ${CMAKE_SOURCE_DIR}/LICENSE ${CMAKE_SOURCE_DIR}/tools/omniposed/daemon.example.yaml
        DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT runtime)

# cpack -G DEB: one package per component, named the Debian way; the programs' dependencies
# from the shared-library scan (dpkg-shlibdeps). The static libraries need no shared library,
# but find_package(omnipose) finds the -dev packages of what they link: those are listed.
set(CPACK_PACKAGE_NAME omnipose)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
# Each package's description: its first line is the synopsis (no CPACK_PACKAGE_DESCRIPTION_SUMMARY,
# which CPack would put first in both).
set(CPACK_PACKAGE_CONTACT "omnipose maintainers <omnipose@localhost>")
set(CPACK_RESOURCE_FILE_LICENSE ${CMAKE_SOURCE_DIR}/LICENSE)
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_COMPONENTS_ALL runtime dev)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_NAME omnipose)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SECTION science)
# lcm-spy (liblcm-bin) needs both to show the poses with share/java/omnipose_lcm_types.jar.
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SUGGESTS "liblcm-bin, liblcm-java, libjchart2d-java")
set(CPACK_DEBIAN_RUNTIME_DESCRIPTION
    "pose of an omni-directional camera over LCM (daemon and tools)
Pose of an omni-directional camera from sinusoid fitting of iFMI motions: the daemon
omniposed (systemd unit, example configuration), the tools (replay, synth, eval,
calibrate, listen, plots) and the LCM message types for Python and Java.")
set(CPACK_DEBIAN_DEV_PACKAGE_NAME libomnipose-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS
    "libopencv-dev, libopencv-contrib-dev, libeigen3-dev (>= 3.4), libyaml-cpp-dev, libfftw3-dev, zlib1g-dev, liblcm-dev, libglib2.0-dev, pkg-config")
set(CPACK_DEBIAN_DEV_DESCRIPTION
    "pose of an omni-directional camera (development files)
Headers, static libraries and the CMake package (find_package(omnipose)) of the
omnipose library, the LCM type definitions and their generated C++ headers.")
set(CPACK_COMPONENT_RUNTIME_DISPLAY_NAME "omnipose daemon and tools")
set(CPACK_COMPONENT_DEV_DISPLAY_NAME "omnipose development files")
include(CPack)
