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

# hw_add_test(NAME name SRCS foo_test.cc DEPS ...)
# A GoogleTest executable with tests/support.h; every TEST becomes one ctest test. HW_SOURCE_DIR and
# HW_BINARY_DIR let tests find the repository and the build's own outputs.
function(hw_add_test)
  cmake_parse_arguments(HW "" "NAME" "SRCS;DEPS" ${ARGN})
  add_executable(${HW_NAME} ${HW_SRCS})
  target_link_libraries(${HW_NAME} PRIVATE ${HW_DEPS} hw_test_support GTest::gtest GTest::gtest_main
                        GTest::gmock)
  hw_set_target_options(${HW_NAME})
  target_compile_definitions(${HW_NAME} PRIVATE
    HW_SOURCE_DIR="${PROJECT_SOURCE_DIR}" HW_BINARY_DIR="${PROJECT_BINARY_DIR}")
  gtest_discover_tests(${HW_NAME} DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT 300)
endfunction()
