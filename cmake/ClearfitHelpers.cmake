# clearfit_module(NAME SOURCES ... [PUBLIC_LINKS ...] [PRIVATE_LINKS ...] [MODULE_DEPENDS ...])
# One library target per module folder: clearfit_<NAME>, alias clearfit::<NAME>.
# MODULE_DEPENDS may only name modules that come earlier in CLEARFIT_MODULE_ORDER.
function(clearfit_module NAME)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_LINKS;PRIVATE_LINKS;MODULE_DEPENDS" ${ARGN})
  list(FIND CLEARFIT_MODULE_ORDER ${NAME} self_rank)
  if(self_rank EQUAL -1)
    message(FATAL_ERROR "clearfit: module '${NAME}' is not in CLEARFIT_MODULE_ORDER")
  endif()
  foreach(dep IN LISTS ARG_MODULE_DEPENDS)
    list(FIND CLEARFIT_MODULE_ORDER ${dep} dep_rank)
    if(dep_rank EQUAL -1 OR NOT dep_rank LESS self_rank)
      message(FATAL_ERROR
        "clearfit: module '${NAME}' may not depend on '${dep}' "
        "(module order: ${CLEARFIT_MODULE_ORDER})")
    endif()
  endforeach()
  set(target clearfit_${NAME})
  add_library(${target} STATIC ${ARG_SOURCES})
  add_library(clearfit::${NAME} ALIAS ${target})
  target_include_directories(${target} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic)
  list(TRANSFORM ARG_MODULE_DEPENDS PREPEND clearfit::)
  target_link_libraries(${target} PUBLIC ${ARG_MODULE_DEPENDS} ${ARG_PUBLIC_LINKS}
                                  PRIVATE ${ARG_PRIVATE_LINKS})
endfunction()

# clearfit_test(MODULE NAME SOURCES ... [LINKS ...] [PREFIX p] [PROPERTIES ...]): a GoogleTest
# program test_<p>_<NAME> whose tests show in ctest as <p>/Suite.Case (p defaults to MODULE).
function(clearfit_test MODULE NAME)
  cmake_parse_arguments(ARG "" "PREFIX" "SOURCES;LINKS;PROPERTIES" ${ARGN})
  if(NOT ARG_PREFIX)
    set(ARG_PREFIX ${MODULE})
  endif()
  set(target test_${ARG_PREFIX}_${NAME})
  add_executable(${target} ${ARG_SOURCES})
  target_link_libraries(${target} PRIVATE clearfit::${MODULE} ${ARG_LINKS} GTest::gmock GTest::gtest_main)
  target_compile_options(${target} PRIVATE -Wall -Wextra)
  target_compile_definitions(${target} PRIVATE
    CLEARFIT_TEST_DATA_DIR="${CMAKE_SOURCE_DIR}/tests/data"
    CLEARFIT_TOOLS_DIR="${CMAKE_SOURCE_DIR}/tests/tools"
    CLEARFIT_SAMPLES_DIR="${CMAKE_SOURCE_DIR}/samples"
    CLEARFIT_BINARY_DIR="${CMAKE_BINARY_DIR}")
  if(ARG_PROPERTIES)
    gtest_discover_tests(${target} TEST_PREFIX "${ARG_PREFIX}/" DISCOVERY_TIMEOUT 60 PROPERTIES ${ARG_PROPERTIES})
  else()
    gtest_discover_tests(${target} TEST_PREFIX "${ARG_PREFIX}/" DISCOVERY_TIMEOUT 60)
  endif()
endfunction()
