# ctest script: installs this build into a fresh prefix, configures and builds
# tests/install/downstream against it with find_package(omnipose), and runs the program.
# The libraries and the CMake package are in <prefix>/LIBDIR (lib/<triplet> on multiarch).
# -D BUILD_DIR=<this build> -D SOURCE_DIR=<tests/install/downstream> -D WORK_DIR=<scratch>
include(${BUILD_DIR}/omnipose_install_dirs.cmake)  # OMNIPOSE_INSTALL_LIBDIR
set(LIBDIR ${OMNIPOSE_INSTALL_LIBDIR})
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
include(${CMAKE_CURRENT_LIST_DIR}/run_step.cmake)  # run()
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK_DIR}/prefix)
run(${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/build -DCMAKE_BUILD_TYPE=Release
    -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix)
file(STRINGS ${WORK_DIR}/build/CMakeCache.txt omnipose_dir REGEX "^omnipose_DIR:")
if(NOT omnipose_dir STREQUAL "omnipose_DIR:PATH=${WORK_DIR}/prefix/${LIBDIR}/cmake/omnipose")
  message(FATAL_ERROR "find_package(omnipose) found: ${omnipose_dir}")
endif()
foreach(file ${LIBDIR}/libomnipose.a ${LIBDIR}/libomnipose_io.a
             lib/python3/dist-packages/omnipose/pose_t.py share/omnipose/lcm_types/pose_t.lcm
             include/omnipose/lcm/omnipose/pose_t.hpp include/omnipose/io/dataset.hpp
             include/omnipose/io/trajectory.hpp include/omnipose/synth/synth.hpp
             include/omnipose/eval/evaluation.hpp)
  if(NOT EXISTS ${WORK_DIR}/prefix/${file})
    message(FATAL_ERROR "the installed copy lacks ${file}")
  endif()
endforeach()
# The headers of io, synth and eval are in their own folders, not among the core's.
foreach(file dataset.hpp trajectory.hpp synth.hpp evaluation.hpp)
  if(EXISTS ${WORK_DIR}/prefix/include/omnipose/${file})
    message(FATAL_ERROR "include/omnipose/${file} is installed beside the core's headers")
  endif()
endforeach()
run(${CMAKE_COMMAND} --build ${WORK_DIR}/build)
run(${WORK_DIR}/build/downstream ${WORK_DIR})
message(STATUS "${last_output}")
if(NOT last_output MATCHES "first frame accepted, \\|yaw\\| 0\\.03[0-9]+ rad \\(rendered 0\\.03491\\), proposed panorama 1885x257, pose_t encodes to")
  message(FATAL_ERROR "unexpected output: ${last_output}")
endif()
# The README's 15-line example is this program, letter for letter (its first line, a comment
# naming it, aside); run on the two frames just written, it reads a yaw of 2 degrees.
file(READ ${SOURCE_DIR}/../../../README.md readme)
string(REGEX MATCH "```cpp\n([^`]*)```" readme_block "${readme}")
set(readme_example "${CMAKE_MATCH_1}")
file(READ ${SOURCE_DIR}/two_images.cpp example)
string(REGEX REPLACE "^//[^\n]*\n" "" example "${example}")
if(NOT readme_example STREQUAL example)
  message(FATAL_ERROR "README.md's cpp example is not tests/install/downstream/two_images.cpp:\n"
                      "${readme_example}\n---\n${example}")
endif()
run(${WORK_DIR}/build/two_images ${WORK_DIR}/calibration.yaml ${WORK_DIR}/first.png
    ${WORK_DIR}/second.png)
message(STATUS "${last_output}")
if(NOT last_output MATCHES "rotation vector -?0\\.000[0-9][0-9] -?0\\.000[0-9][0-9] -?0\\.03[45][0-9][0-9] rad")
  message(FATAL_ERROR "two_images: unexpected output: ${last_output}")
endif()
# The unit names the installed omniposed.
file(READ ${WORK_DIR}/prefix/lib/systemd/system/omniposed.service unit)
if(NOT unit MATCHES "ExecStart=${WORK_DIR}/prefix/bin/omniposed ")
  message(FATAL_ERROR "the unit does not start the installed omniposed:\n${unit}")
endif()
run(${WORK_DIR}/prefix/bin/omniposed --help)
