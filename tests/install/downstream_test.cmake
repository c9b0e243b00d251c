# ctest script: installs this build into a fresh prefix, configures and builds
# tests/install/downstream against it with find_package(omnipose), and runs the program.
# -D BUILD_DIR=<this build> -D SOURCE_DIR=<tests/install/downstream> -D WORK_DIR=<scratch>
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  set(last_output "${out}" PARENT_SCOPE)
endfunction()
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK_DIR}/prefix)
run(${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/build -DCMAKE_BUILD_TYPE=Release
    -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix)
run(${CMAKE_COMMAND} --build ${WORK_DIR}/build)
run(${WORK_DIR}/build/downstream)
message(STATUS "${last_output}")
if(NOT last_output MATCHES "first frame accepted, \\|yaw\\| 0\\.03[0-9]+ rad \\(rendered 0\\.03491\\), proposed panorama 1885x257, pose_t encodes to")
  message(FATAL_ERROR "unexpected output: ${last_output}")
endif()
# The unit names the installed omniposed.
file(READ ${WORK_DIR}/prefix/lib/systemd/system/omniposed.service unit)
if(NOT unit MATCHES "ExecStart=${WORK_DIR}/prefix/bin/omniposed ")
  message(FATAL_ERROR "the unit does not start the installed omniposed:\n${unit}")
endif()
run(${WORK_DIR}/prefix/bin/omniposed --help)
