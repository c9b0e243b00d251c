# ctest script: `cpack -G DEB` of this build into a scratch folder must make two packages:
#   omnipose         the programs (omniposed --help works when unpacked), the unit under
#                    /lib/systemd/system starting /usr/bin/omniposed, the docs, the LCM types
#                    for Python (which decode a logged pose when unpacked) and Java; its
#                    shared-library dependencies from dpkg-shlibdeps;
#   libomnipose-dev  headers, static libraries and the CMake package under the multiarch
#                    /usr/lib/<triplet>, the .lcm files and the C++ LCM headers; depends on the
#                    -dev packages find_package(omnipose) looks for, not on omnipose; a project
#                    configures against the unpacked copy with find_package(omnipose).
# -D BUILD_DIR=<this build> -D WORK_DIR=<scratch> -D SOURCE_DIR=<tests/install>
# -D MULTIARCH=<triplet> -D PYTHON=<python3 or empty> -D WRITER=<pose_log_writer>
# -D JAVA_TYPES=<ON when omnipose_lcm_types.jar is built>
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
include(${CMAKE_CURRENT_LIST_DIR}/run_step.cmake)  # run()
# Each of `paths` must (or with NOT, must not) be in the listing `listing` of `package`.
function(expect_in package listing)
  set(negate OFF)
  foreach(path IN LISTS ARGN)
    if(path STREQUAL "NOT")
      set(negate ON)
      continue()
    endif()
    string(FIND "${listing}" " ./${path}" at)
    if(negate AND NOT at EQUAL -1)
      message(FATAL_ERROR "${package} holds ./${path}, which belongs to the other package")
    elseif(NOT negate AND at EQUAL -1)
      message(FATAL_ERROR "${package} lacks ./${path}:\n${listing}")
    endif()
  endforeach()
endfunction()

run(cpack -G DEB --config ${BUILD_DIR}/CPackConfig.cmake -B ${WORK_DIR})
file(GLOB runtime_deb ${WORK_DIR}/omnipose_*.deb)
file(GLOB dev_deb ${WORK_DIR}/libomnipose-dev_*.deb)
file(GLOB all_debs ${WORK_DIR}/*.deb)
list(LENGTH runtime_deb runtime_count)
list(LENGTH dev_deb dev_count)
list(LENGTH all_debs count)
if(NOT runtime_count EQUAL 1 OR NOT dev_count EQUAL 1 OR NOT count EQUAL 2)
  message(FATAL_ERROR "expected omnipose_*.deb and libomnipose-dev_*.deb in ${WORK_DIR}, found: ${all_debs}")
endif()

# omnipose: the programs' shared libraries.
run(dpkg-deb -f ${runtime_deb} Package Version Depends)
message(STATUS "omnipose:\n${last_output}")
string(REGEX MATCH "Version: ([^\n]+)" _ "${last_output}")
set(version "${CMAKE_MATCH_1}")
foreach(dep libopencv-core406 libyaml-cpp0.7 libfftw3-single3 liblcm1)
  if(NOT last_output MATCHES "${dep}")
    message(FATAL_ERROR "omnipose does not depend on ${dep}: ${last_output}")
  endif()
endforeach()
# libomnipose-dev: what find_package(omnipose) needs; the same version; not the programs.
run(dpkg-deb -f ${dev_deb} Package Version Section Depends)
message(STATUS "libomnipose-dev:\n${last_output}")
if(NOT last_output MATCHES "Version: ${version}\n" OR NOT last_output MATCHES "Section: libdevel")
  message(FATAL_ERROR "libomnipose-dev: unexpected control fields: ${last_output}")
endif()
string(REGEX MATCH "Depends: [^\n]+" dev_depends "${last_output}")
foreach(dep libopencv-dev libopencv-contrib-dev libeigen3-dev libyaml-cpp-dev libfftw3-dev
            zlib1g-dev liblcm-dev)
  if(NOT dev_depends MATCHES "${dep}")
    message(FATAL_ERROR "libomnipose-dev does not depend on ${dep}: ${dev_depends}")
  endif()
endforeach()
if(dev_depends MATCHES "(^|[ ,])omnipose([ ,(]|$)")
  message(FATAL_ERROR "libomnipose-dev depends on omnipose: ${dev_depends}")
endif()

# Contents.
set(libdir usr/lib/${MULTIARCH})
run(dpkg-deb -c ${runtime_deb})
set(runtime_listing "${last_output}")
run(dpkg-deb -c ${dev_deb})
set(dev_listing "${last_output}")
set(runtime_paths usr/bin/omniposed usr/bin/omnipose-replay usr/bin/omnipose-calibrate
    lib/systemd/system/omniposed.service usr/share/doc/omnipose/DESIGN.md
    usr/share/doc/omnipose/daemon.example.yaml
    usr/lib/python3/dist-packages/omnipose/__init__.py
    usr/lib/python3/dist-packages/omnipose/pose_t.py)
if(JAVA_TYPES)
  list(APPEND runtime_paths usr/share/java/omnipose_lcm_types.jar)
endif()
set(dev_paths usr/include/omnipose/pipeline.hpp usr/include/omnipose/calibrate/
    usr/include/omnipose/lcm/omnipose/pose_t.hpp ${libdir}/libomnipose.a
    ${libdir}/libomnipose_calibrate.a ${libdir}/cmake/omnipose/omniposeConfig.cmake
    ${libdir}/cmake/omnipose/omniposeTargets.cmake usr/share/omnipose/lcm_types/pose_t.lcm)
expect_in(omnipose "${runtime_listing}" ${runtime_paths} NOT usr/include/ ${libdir}/ usr/share/omnipose/)
expect_in(libomnipose-dev "${dev_listing}" ${dev_paths} NOT usr/bin/ lib/systemd/ usr/lib/python3/
          usr/include/omnipose/baselines/
          usr/share/java/ usr/lib/libomnipose.a usr/lib/cmake/)

# The unpacked runtime package works.
run(dpkg-deb -x ${runtime_deb} ${WORK_DIR}/runtime)
file(READ ${WORK_DIR}/runtime/lib/systemd/system/omniposed.service unit)
if(NOT unit MATCHES "ExecStart=/usr/bin/omniposed " OR
   NOT unit MATCHES "Documentation=file:///usr/share/doc/omnipose/DESIGN.md")
  message(FATAL_ERROR "unexpected unit:\n${unit}")
endif()
run(${WORK_DIR}/runtime/usr/bin/omniposed --help)
if(NOT last_output MATCHES "usage: omniposed --config")
  message(FATAL_ERROR "omniposed --help printed: ${last_output}")
endif()
if(PYTHON)
  run(${WRITER} ${WORK_DIR}/poses.lcmlog)
  run(${CMAKE_COMMAND} -E env PYTHONPATH=${WORK_DIR}/runtime/usr/lib/python3/dist-packages
      PYTHONDONTWRITEBYTECODE=1 ${PYTHON} ${SOURCE_DIR}/decode_pose_log.py ${WORK_DIR}/poses.lcmlog)
  if(NOT last_output MATCHES "2 poses decoded and checked")
    message(FATAL_ERROR "the packaged Python types: ${last_output}")
  endif()
endif()

# find_package(omnipose) finds the unpacked development package in its multiarch folder.
run(dpkg-deb -x ${dev_deb} ${WORK_DIR}/dev)
run(${CMAKE_COMMAND} -S ${SOURCE_DIR}/downstream -B ${WORK_DIR}/downstream
    -DCMAKE_PREFIX_PATH=${WORK_DIR}/dev/usr)
file(STRINGS ${WORK_DIR}/downstream/CMakeCache.txt omnipose_dir REGEX "^omnipose_DIR:")
if(NOT omnipose_dir STREQUAL "omnipose_DIR:PATH=${WORK_DIR}/dev/${libdir}/cmake/omnipose")
  message(FATAL_ERROR "find_package(omnipose) found: ${omnipose_dir}")
endif()
