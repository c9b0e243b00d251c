# ctest script: the generated LCM types for Python (and Java) decode a logged pose.
# pose_log_writer writes an LCM log through LCM's file provider; then
#   LANGUAGE=python: decode_pose_log.py reads the log format itself and decodes with the
#                    generated module (PYTHON_DIR on PYTHONPATH);
#   LANGUAGE=java:   DecodePoseLog.java is compiled against lcm.jar and run with
#                    CLASSPATH=<omnipose_lcm_types.jar>, finding the types as lcm-spy does.
# -D WRITER=<pose_log_writer> -D WORK_DIR=<scratch> -D SOURCE_DIR=<tests/install>
# -D LANGUAGE=python -D PYTHON=<python3> -D PYTHON_DIR=<folder holding omnipose/>
# -D LANGUAGE=java -D JAVAC=<javac> -D JAVA=<java> -D LCM_JAR=<lcm.jar> -D TYPES_JAR=<jar>
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
include(${CMAKE_CURRENT_LIST_DIR}/run_step.cmake)  # run()
set(log ${WORK_DIR}/poses.lcmlog)
run(${WRITER} ${log})
if(LANGUAGE STREQUAL "python")
  run(${CMAKE_COMMAND} -E env PYTHONPATH=${PYTHON_DIR} PYTHONDONTWRITEBYTECODE=1
      ${PYTHON} ${SOURCE_DIR}/decode_pose_log.py ${log})
  set(expected "2 poses decoded and checked")
elseif(LANGUAGE STREQUAL "java")
  run(${JAVAC} -d ${WORK_DIR}/classes -cp ${LCM_JAR} ${SOURCE_DIR}/DecodePoseLog.java)
  run(${CMAKE_COMMAND} -E env CLASSPATH=${TYPES_JAR}
      ${JAVA} -cp ${LCM_JAR}:${WORK_DIR}/classes DecodePoseLog ${log})
  set(expected "2 poses decoded and checked")
else()
  message(FATAL_ERROR "LANGUAGE must be python or java, not '${LANGUAGE}'")
endif()
message(STATUS "${last_output}")
if(NOT last_output MATCHES "${expected}")
  message(FATAL_ERROR "the decoder did not confirm the poses: ${last_output}")
endif()
