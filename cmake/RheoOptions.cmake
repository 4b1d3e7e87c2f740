# Compile flags shared by every Rheo target, on an INTERFACE target rather than global flags.
add_library(rheo_options INTERFACE)
target_compile_options(rheo_options INTERFACE -Wall -Wextra)
target_compile_features(rheo_options INTERFACE cxx_std_20)

if(RHEO_SANITIZE)
  message(STATUS "Rheo: sanitizers ${RHEO_SANITIZE}")
  add_compile_options(-fsanitize=${RHEO_SANITIZE} -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  add_link_options(-fsanitize=${RHEO_SANITIZE})
endif()

# rheo_add_test(NAME SOURCES... LIBS ...): one GoogleTest binary, each case its own ctest test.
function(rheo_add_test name)
  cmake_parse_arguments(T "" "TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${T_SOURCES})
  target_link_libraries(${name} PRIVATE ${T_LIBS} GTest::gtest GTest::gtest_main rheo_options)
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 120)
  endif()
  gtest_discover_tests(${name} DISCOVERY_MODE PRE_TEST
    PROPERTIES TIMEOUT ${T_TIMEOUT} LABELS "${T_LABELS}")
endfunction()
