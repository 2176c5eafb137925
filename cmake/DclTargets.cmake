# Helpers that give every dcl-slam target the same standard, warnings and layout.

# dcl_set_options(<target>): C++20, -Wall -Wextra, warnings as errors when DCL_WERROR is on.
function(dcl_set_options target)
  target_compile_features(${target} PUBLIC cxx_std_20)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic)
  if(DCL_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# dcl_add_precompiled_headers(): the target dcl_pch, whose precompiled header
# (the standard library, Eigen, fmt and spdlog, which nearly every file of the
# project includes) the libraries and the program reuse instead of parsing
# those headers again in each of their files.
# With the tests, a second one, dcl_pch_tests, compiled as the test programs
# are (DCL_TEST_OPTIMIZATION): GCC refuses a precompiled header built at
# another optimisation level.
function(dcl_add_precompiled_headers)
  set(headers <algorithm> <array> <cmath> <cstddef> <cstdint> <functional> <limits> <map>
              <memory> <optional> <set> <span> <string> <string_view> <utility> <vector>
              <Eigen/Core> <Eigen/Geometry> <fmt/format.h> <spdlog/spdlog.h>)
  set(targets dcl_pch)
  if(DCL_BUILD_TESTS)
    list(APPEND targets dcl_pch_tests)
  endif()
  foreach(target ${targets})
    add_library(${target} STATIC ${PROJECT_SOURCE_DIR}/cmake/pch.cpp)
    target_link_libraries(${target} PUBLIC Eigen3::Eigen spdlog::spdlog fmt::fmt)
    dcl_set_options(${target})
    target_precompile_headers(${target} PRIVATE ${headers})
  endforeach()
  if(DCL_BUILD_TESTS)
    target_compile_options(dcl_pch_tests PRIVATE ${DCL_TEST_OPTIMIZATION})
  endif()
endfunction()

# dcl_use_precompiled_headers(<target> [<pch target>]): <target> reuses the
# header of dcl_pch, or of the one named (when DCL_PCH made it; a file whose
# flags differ parses the headers itself).
function(dcl_use_precompiled_headers target)
  set(pch dcl_pch)
  if(ARGC GREATER 1)
    set(pch ${ARGV1})
  endif()
  if(TARGET ${pch})
    target_precompile_headers(${target} REUSE_FROM ${pch})
    # GCC 12 loses the system-header status of code it reads from a
    # precompiled header, and then reports its known false positives in
    # std::string's inlined copies (-Warray-bounds, -Wstringop-overflow,
    # -Wstringop-overread) as if they were ours; the same files compiled
    # without it report none.
    target_compile_options(
      ${target} PRIVATE
      $<$<CXX_COMPILER_ID:GNU>:-Wno-array-bounds -Wno-stringop-overflow -Wno-stringop-overread>)
  endif()
endfunction()

# dcl_unity_batches(<target> <size>): <target>'s files compile <size> to a
# translation unit (0: all in one), which parses the headers and instantiates
# the templates they share once per batch instead of once per file. File-local
# names must then differ between the files of a target. GCC warns when a
# class of one file holds a type of that file's anonymous namespace, as most
# pImpl classes do, once the file is included by the batch: not a defect.
function(dcl_unity_batches target size)
  set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE ${size})
  target_compile_options(${target} PRIVATE $<$<CXX_COMPILER_ID:GNU>:-Wno-subobject-linkage>)
endfunction()

# dcl_add_module(<name> SOURCES ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...])
# Makes the library target dcl_<name> with the alias dcl::<name>.
function(dcl_add_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(dcl_${name} ${ARG_SOURCES})
  add_library(dcl::${name} ALIAS dcl_${name})
  target_include_directories(dcl_${name} PUBLIC ${PROJECT_SOURCE_DIR}/include)
  target_link_libraries(dcl_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  dcl_set_options(dcl_${name})
  dcl_use_precompiled_headers(dcl_${name})
  if(DCL_UNITY)
    dcl_unity_batches(dcl_${name} ${DCL_UNITY_BATCH})
  endif()
endfunction()

# dcl_add_test(<name> [SCAN_CACHE] SOURCES ... DEPS ...): a GoogleTest
# executable whose cases ctest lists; SCAN_CACHE: its cases share the suite's
# scan cache (tests/CMakeLists.txt), for the cases that replay one dataset
# each in its own process.
function(dcl_add_test name)
  cmake_parse_arguments(ARG "SCAN_CACHE" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE DCL_DATA_DIR="${DCL_DATA_DIR}"
                                             DCL_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  dcl_set_options(${name})
  target_compile_options(${name} PRIVATE ${DCL_TEST_OPTIMIZATION})
  dcl_use_precompiled_headers(${name} dcl_pch_tests)
  if(DCL_UNITY)
    dcl_unity_batches(${name} ${DCL_UNITY_BATCH})
  endif()
  # One variable per property: gtest_discover_tests writes each list element
  # of PROPERTIES out as an argument of its own, so a second variable in
  # ENVIRONMENT would become a property.
  set(properties ENVIRONMENT "DCL_DATA_DIR=${DCL_DATA_DIR}")
  if(ARG_SCAN_CACHE AND DCL_TEST_SCAN_CACHE)
    list(APPEND properties ENVIRONMENT_MODIFICATION "${DCL_TEST_SCAN_CACHE_ENV}")
  endif()
  gtest_discover_tests(${name} DISCOVERY_MODE PRE_TEST PROPERTIES ${properties})
endfunction()
