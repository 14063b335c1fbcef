# Helpers that keep each module's CMakeLists.txt to a few lines.
#
# xgauge_module(NAME SOURCES ... DEPS ...)
#   A static library xgauge_<NAME> with alias xgauge::<NAME>. Its headers
#   live in internal/xgauge/<NAME>/ (the library's inside: only the front
#   door, include/xgauge/xgauge.h, is installed); DEPS lists the lower modules and external
#   targets it links against (PUBLIC), so including a higher module fails to
#   link. When XGAUGE_INSTALL is on, the library joins the export set
#   xgaugeTargets (installed as xgauge::<NAME> by the top CMakeLists.txt), so
#   a new module is installed and exported without further changes.
# xgauge_test(NAME SOURCES ... DEPS ...)
#   A GoogleTest executable registered with CTest.

function(xgauge_compile_options target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow
    -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Wunused
    -Woverloaded-virtual -Wnull-dereference -Wdouble-promotion -Wformat=2
    # GCC 12 reports false positives inside Eigen and its own SIMD headers.
    -Wno-maybe-uninitialized)
  if(XGAUGE_WARNINGS_AS_ERRORS)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(XGAUGE_NATIVE)
    target_compile_options(${target} PRIVATE -march=native)
  endif()
  # No FMA contraction: the renderer's exact predicates and determinism at
  # any thread count rely on every expression rounding the same way.
  # -fno-trapping-math (FP exception flags are never read) lets GCC vectorize
  # ceil/floor and the renderer's span loops; it does not change any result.
  target_compile_options(${target} PRIVATE -ffp-contract=off -fno-math-errno -fno-trapping-math)
endfunction()

function(xgauge_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_library(xgauge_${name} STATIC ${ARG_SOURCES})
  add_library(xgauge::${name} ALIAS xgauge_${name})
  # include/ holds the front door (xgauge/xgauge.h), internal/ the modules'
  # own headers (used in this tree, never installed), the build tree's
  # include/ the generated xgauge/version.h.
  target_include_directories(xgauge_${name}
    PUBLIC $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include>
           $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/internal>
           $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/include>
           $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>
    PRIVATE ${PROJECT_SOURCE_DIR}/src)
  target_link_libraries(xgauge_${name} PUBLIC ${ARG_DEPS})
  xgauge_compile_options(xgauge_${name})
  set_target_properties(xgauge_${name} PROPERTIES EXPORT_NAME ${name})
  set_property(GLOBAL APPEND PROPERTY XGAUGE_MODULES ${name})
  if(XGAUGE_INSTALL)
    install(TARGETS xgauge_${name} EXPORT xgaugeTargets
      ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
      LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
      RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  endif()
endfunction()

function(xgauge_test name)
  if(NOT XGAUGE_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_include_directories(${name} PRIVATE ${PROJECT_SOURCE_DIR}/src)
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE
    XGAUGE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  xgauge_compile_options(${name})
  gtest_discover_tests(${name} TEST_PREFIX "${name}." DISCOVERY_TIMEOUT 60)
endfunction()
