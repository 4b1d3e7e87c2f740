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
  cmake_parse_arguments(T "SERIAL" "TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${T_SOURCES})
  target_link_libraries(${name} PRIVATE ${T_LIBS} GTest::gtest GTest::gtest_main rheo_options)
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 120)
  endif()
  # SERIAL: the tests measure the loop's rate or a predicted tick cost against the machine, so
  # ctest runs them alone (ctest -j2 on two cores beside a compile-heavy test inflated the
  # measured tick cost past the budget and made the loop late).
  set(extra "")
  if(T_SERIAL)
    set(extra RUN_SERIAL TRUE)
  endif()
  gtest_discover_tests(${name} DISCOVERY_MODE PRE_TEST
    PROPERTIES ${extra} TIMEOUT ${T_TIMEOUT} LABELS "${T_LABELS}")
endfunction()

# rheo_include_root(TARGET PREFIX DIR): the headers in DIR are reachable as "PREFIX/name.h" by
# TARGET and by the targets that link it, and by nothing else. Each library gets an include root
# of its own (a folder in the build tree holding one link, PREFIX -> DIR), so an include against
# the direction of the layers (sim including daemon/..., the loop including daemon/device/...)
# fails to compile: the header is simply not on that target's include path. The source folders
# themselves are never on an include path; "../" in an include is refused by scripts/format.
function(rheo_include_root target prefix dir)
  set(root ${CMAKE_BINARY_DIR}/include-roots/${target})
  set(link ${root}/${prefix})
  get_filename_component(parent ${link} DIRECTORY)
  file(MAKE_DIRECTORY ${parent})
  if(NOT IS_SYMLINK ${link})
    file(CREATE_LINK ${dir} ${link} SYMBOLIC)
  endif()
  get_target_property(type ${target} TYPE)
  if(type STREQUAL "INTERFACE_LIBRARY")
    target_include_directories(${target} INTERFACE $<BUILD_INTERFACE:${root}>)
  else()
    target_include_directories(${target} PUBLIC $<BUILD_INTERFACE:${root}>)
  endif()
endfunction()
