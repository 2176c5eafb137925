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

# dcl_add_module(<name> SOURCES ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...])
# Makes the library target dcl_<name> with the alias dcl::<name>.
function(dcl_add_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(dcl_${name} ${ARG_SOURCES})
  add_library(dcl::${name} ALIAS dcl_${name})
  target_include_directories(dcl_${name} PUBLIC ${PROJECT_SOURCE_DIR}/include)
  target_link_libraries(dcl_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  dcl_set_options(dcl_${name})
endfunction()

# dcl_add_test(<name> SOURCES ... DEPS ...): a GoogleTest executable whose cases ctest lists.
function(dcl_add_test name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE DCL_DATA_DIR="${DCL_DATA_DIR}"
                                             DCL_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  dcl_set_options(${name})
  gtest_discover_tests(${name} DISCOVERY_MODE PRE_TEST
                       PROPERTIES ENVIRONMENT "DCL_DATA_DIR=${DCL_DATA_DIR}")
endfunction()
