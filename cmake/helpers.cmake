# One helper per kind of target. Every target sees includes rooted at the repository
# (#include "core/camera.h") and builds with the project's warnings.

set(HW_WARNINGS -Wall -Wextra -Wpedantic -Wshadow=local -Wnon-virtual-dtor -Wcast-align
                -Wunused -Woverloaded-virtual -Wnull-dereference -Wdouble-promotion
                -Wformat=2 -Wimplicit-fallthrough)

# -ffp-contract=off: GCC fuses a·b + c into one FMA (one rounding instead of two) wherever the
# target has FMA unless told not to, which C++ mode allows by default; our SIMD kernels'
# x86-64-v4 clones (target_clones) have it, so on an AVX-512 CPU they rounded differently from
# the scalar code they must match bit for bit (and from the AVX2 clone another machine runs).
set(HW_FLOAT_OPTIONS -ffp-contract=off)

function(hw_set_target_options target)
  target_compile_options(${target} PRIVATE ${HW_WARNINGS} ${HW_FLOAT_OPTIONS})
  target_include_directories(${target} PUBLIC "${PROJECT_SOURCE_DIR}")
endfunction()

# hw_add_library(NAME name SRCS a.cc b.cc DEPS dep1 dep2)
function(hw_add_library)
  cmake_parse_arguments(HW "" "NAME" "SRCS;DEPS" ${ARGN})
  add_library(${HW_NAME} STATIC ${HW_SRCS})
  target_link_libraries(${HW_NAME} PUBLIC ${HW_DEPS})
  hw_set_target_options(${HW_NAME})
endfunction()

# hw_add_executable(NAME name SRCS main.cc DEPS ...)
function(hw_add_executable)
  cmake_parse_arguments(HW "" "NAME;OUTPUT_NAME" "SRCS;DEPS" ${ARGN})
  add_executable(${HW_NAME} ${HW_SRCS})
  target_link_libraries(${HW_NAME} PRIVATE ${HW_DEPS})
  hw_set_target_options(${HW_NAME})
  if(HW_OUTPUT_NAME)
    set_target_properties(${HW_NAME} PROPERTIES OUTPUT_NAME ${HW_OUTPUT_NAME})
  endif()
endfunction()

# The headers nearly every test file includes, parsed once for all of them: GoogleTest, gmock,
# Eigen and OpenCV's core took ~2 s of each test file's compilation, ~150 files.
set(HW_TEST_PCH_HEADERS <gtest/gtest.h> <gmock/gmock.h> <Eigen/Core> <Eigen/Geometry> <opencv2/core.hpp>
                        <algorithm> <cmath> <filesystem> <random> <string> <vector>)
# What a test links and defines besides its own DEPS; the precompiled header is built with
# the same, since GCC uses it only for a file compiled with the macros it was made with
# (-pthread defines _REENTRANT, as the pkg-config flags of Cairo and Pango do for the tests
# that link them).
set(HW_TEST_LIBS GTest::gtest GTest::gtest_main GTest::gmock Eigen3::Eigen opencv_core)
set(HW_TEST_OPTIONS -pthread)

# The target whose precompiled header every test reuses (hw_add_test makes it once).
function(hw_add_test_pch)
  if(TARGET hw_test_pch)
    return()
  endif()
  set(anchor "${PROJECT_BINARY_DIR}/hw_test_pch.cc")
  file(CONFIGURE OUTPUT "${anchor}" CONTENT "// The tests' precompiled header (cmake/helpers.cmake).\n")
  add_library(hw_test_pch OBJECT "${anchor}")
  target_link_libraries(hw_test_pch PRIVATE ${HW_TEST_LIBS})
  hw_set_target_options(hw_test_pch)
  target_compile_options(hw_test_pch PRIVATE ${HW_TEST_OPTIONS})
  target_compile_definitions(hw_test_pch PRIVATE
    HW_SOURCE_DIR="${PROJECT_SOURCE_DIR}" HW_BINARY_DIR="${PROJECT_BINARY_DIR}")
  target_precompile_headers(hw_test_pch PRIVATE ${HW_TEST_PCH_HEADERS})
endfunction()

# hw_add_test(NAME name SRCS foo_test.cc DEPS ...)
# A GoogleTest executable with tests/support.h; every TEST becomes one ctest test. HW_SOURCE_DIR and
# HW_BINARY_DIR let tests find the repository and the build's own outputs.
function(hw_add_test)
  cmake_parse_arguments(HW "" "NAME" "SRCS;DEPS" ${ARGN})
  hw_add_test_pch()
  add_executable(${HW_NAME} ${HW_SRCS})
  target_link_libraries(${HW_NAME} PRIVATE ${HW_DEPS} hw_test_support ${HW_TEST_LIBS})
  hw_set_target_options(${HW_NAME})
  target_compile_options(${HW_NAME} PRIVATE ${HW_TEST_OPTIONS})
  target_compile_definitions(${HW_NAME} PRIVATE
    HW_SOURCE_DIR="${PROJECT_SOURCE_DIR}" HW_BINARY_DIR="${PROJECT_BINARY_DIR}")
  target_precompile_headers(${HW_NAME} REUSE_FROM hw_test_pch)
  gtest_discover_tests(${HW_NAME} DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT 300)
endfunction()
