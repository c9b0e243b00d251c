# Small helpers shared by every component's CMakeLists.txt.

# omnipose_add_subdirectories(): add every direct sub-folder that has a
# CMakeLists.txt, in name order. Components register themselves this way, so
# adding a module never edits a shared list.
function(omnipose_add_subdirectories)
  file(GLOB children RELATIVE ${CMAKE_CURRENT_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR}/*)
  list(SORT children)
  foreach(child IN LISTS children)
    if(IS_DIRECTORY ${CMAKE_CURRENT_SOURCE_DIR}/${child}
       AND EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/${child}/CMakeLists.txt)
      add_subdirectory(${child})
    endif()
  endforeach()
endfunction()

# omnipose_precompile_library(TARGET [header...]): a precompiled header of the library's own
# (PRIVATE: its users never see it) with OpenCV's core, Eigen and the standard headers nearly
# every source includes, plus the given ones. GCC parses them once per library instead of once
# per source: the three libraries that use it compile in 356 CPU s instead of 426 in Release
# (CI compiles them four times: Release, sanitizers, fuzzers, Python).
function(omnipose_precompile_library target)
  target_precompile_headers(${target} PRIVATE
    <opencv2/core.hpp> <Eigen/Core> <Eigen/Geometry>
    <algorithm> <array> <cmath> <cstdint> <limits> <numbers> <optional> <span> <stdexcept>
    <string> <vector> ${ARGN})
endfunction()

# omnipose_add_test(NAME src... [LIBS lib...]): one GoogleTest binary, run by ctest.
# Tests run with the source tree as working directory so they find tests/data. Every test
# may use the renderer (the referee of every sign), datasets and the evaluation.
function(omnipose_add_test name)
  cmake_parse_arguments(ARG "" "" "LIBS" ${ARGN})
  if(OMNIPOSE_SANITIZE AND name IN_LIST OMNIPOSE_ALLOCATION_COUNTING_TESTS)
    # Not even built: the sanitizer owns the allocator (see OMNIPOSE_ALLOCATION_COUNTING_TESTS),
    # and gtest_discover_tests would run the binary at build time.
    message(STATUS "${name}: not built under OMNIPOSE_SANITIZE=${OMNIPOSE_SANITIZE}")
    return()
  endif()
  add_executable(${name} ${ARG_UNPARSED_ARGUMENTS})
  omnipose_tsan_serial_opencv(${name})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} omnipose_synth omnipose_eval omnipose_io
                        GTest::gmock GTest::gtest GTest::gtest_main)
  target_include_directories(${name} PRIVATE ${CMAKE_SOURCE_DIR}/tests/support)  # test_files.hpp
  target_compile_definitions(${name} PRIVATE
    OMNIPOSE_SOURCE_DIR="${CMAKE_SOURCE_DIR}"
    OMNIPOSE_BINARY_DIR="${CMAKE_BINARY_DIR}")
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/tests)
  if(TARGET omnipose_test_pch)
    target_precompile_headers(${name} REUSE_FROM omnipose_test_pch)  # tests/CMakeLists.txt
  endif()
  # Labels: the test folder (tests/daemon -> "daemon"), plus "allocation" (below) and "long".
  get_filename_component(folder ${CMAKE_CURRENT_SOURCE_DIR} NAME)
  set(labels ${folder})
  if(name IN_LIST OMNIPOSE_ALLOCATION_COUNTING_TESTS)
    list(APPEND labels allocation)
  endif()
  gtest_discover_tests(${name} WORKING_DIRECTORY ${CMAKE_SOURCE_DIR} DISCOVERY_TIMEOUT 120)
  # gtest_discover_tests(PROPERTIES LABELS ...) of CMake 3.25 cannot pass a list: it wrote
  # "LABELS daemon allocation", which set the folder label only. The labels are set by a
  # script that ctest runs after the discovered tests' own (${name}_TESTS lists them).
  # The tests named in tests/long_tests.txt also carry "long".
  set(label_script ${CMAKE_CURRENT_BINARY_DIR}/${name}_labels.cmake)
  file(WRITE ${label_script}
       "if(DEFINED ${name}_TESTS)\n"
       "  set_tests_properties(\${${name}_TESTS} PROPERTIES LABELS \"${labels}\")\n"
       "  foreach(long_test ${OMNIPOSE_LONG_TESTS})\n"
       "    list(FIND ${name}_TESTS \"\${long_test}\" index)\n"
       "    if(NOT index EQUAL -1)\n"
       "      set_tests_properties(\"\${long_test}\" PROPERTIES LABELS \"${labels};long\")\n"
       "    endif()\n"
       "  endforeach()\n"
       "endif()\n")
  set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES ${label_script})
endfunction()

# GoogleTest names labelled "long" (the file says which and why; tools/sanitize.sh skips them).
file(STRINGS ${CMAKE_SOURCE_DIR}/tests/long_tests.txt OMNIPOSE_LONG_TESTS REGEX "^[A-Za-z]")
set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${CMAKE_SOURCE_DIR}/tests/long_tests.txt)

# Test binaries whose point is counting heap allocations (they link the one counter,
# tests/support/allocation_counter.hpp, which interposes the malloc family and replaces
# operator new/delete). They carry the ctest label "allocation": a sanitizer build
# (tools/sanitize.sh) excludes them with `ctest -LE allocation`, because ASan/TSan replace the
# allocator themselves (the counter is compiled out there and counts nothing).
set(OMNIPOSE_ALLOCATION_COUNTING_TESTS pipeline_alloc_test registration_alloc_test
    daemon_alloc_test allocation_counter_test libcamera_alloc_test)

# omnipose_tsan_serial_opencv(TARGET): in a ThreadSanitizer build, OpenCV runs its parallel
# loops on the calling thread in TARGET (tests/sanitizers/opencv_serial.cpp says why).
function(omnipose_tsan_serial_opencv target)
  if(OMNIPOSE_SANITIZE STREQUAL "thread")
    target_sources(${target} PRIVATE ${CMAKE_SOURCE_DIR}/tests/sanitizers/opencv_serial.cpp)
  endif()
endfunction()
