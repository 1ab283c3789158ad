# The installable package (docs/embedding.md): `cmake --install` puts the public headers under
# include/fabrik/, the libraries under lib/, and a CMake package `fabrik` (namespace fabrik::,
# with a version file) under lib/cmake/fabrik, so another project does
#   find_package(fabrik 0.1 REQUIRED)  and links  fabrik::solver, fabrik::tracking, ...
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

# fabrik_public(TARGET NAME HEADERS h...): TARGET is exported as fabrik::NAME (and aliased so in
# this build); the listed headers of its folder are the public ones, installed as
# include/fabrik/<folder>/h. Public headers include each other by relative paths only, so they
# resolve the same in src/ and in the install tree; every other header stays internal.
function(fabrik_public target name)
  cmake_parse_arguments(P "" "" "HEADERS" ${ARGN})
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${name})
  add_library(fabrik::${name} ALIAS ${target})
  target_include_directories(${target} INTERFACE $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  # The public headers use C++20 (std::span): a project linking fabrik:: gets it without asking.
  target_compile_features(${target} PUBLIC cxx_std_20)
  file(RELATIVE_PATH folder ${PROJECT_SOURCE_DIR}/src ${CMAKE_CURRENT_SOURCE_DIR})
  install(FILES ${P_HEADERS} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/fabrik/${folder})
  install(TARGETS ${target} EXPORT fabrikTargets ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
  foreach(h ${P_HEADERS})
    set_property(GLOBAL APPEND PROPERTY FABRIK_PUBLIC_HEADERS ${CMAKE_CURRENT_SOURCE_DIR}/${h})
  endforeach()
endfunction()

# fabrik_linked(TARGET NAME): a static library the public ones link, installed and exported
# (fabrik::NAME) for linking only: none of its headers is installed.
function(fabrik_linked target name)
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${name})
  add_library(fabrik::${name} ALIAS ${target})
  install(TARGETS ${target} EXPORT fabrikTargets ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
endfunction()

# Called once at the end of the top-level CMakeLists, when every target is defined.
function(fabrik_install_package)
  set(generated ${PROJECT_BINARY_DIR}/generated)
  configure_file(${PROJECT_SOURCE_DIR}/cmake/version.hpp.in ${generated}/fabrik/version.hpp @ONLY)
  install(FILES ${generated}/fabrik/version.hpp DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/fabrik)
  set(cmake_dir ${CMAKE_INSTALL_LIBDIR}/cmake/fabrik)
  install(EXPORT fabrikTargets NAMESPACE fabrik:: DESTINATION ${cmake_dir})
  configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/fabrikConfig.cmake.in
    ${generated}/fabrikConfig.cmake INSTALL_DESTINATION ${cmake_dir})
  # 0.x: a minor version may change the API, so only the same minor version is compatible.
  write_basic_package_version_file(${generated}/fabrikConfigVersion.cmake
    VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
  install(FILES ${generated}/fabrikConfig.cmake ${generated}/fabrikConfigVersion.cmake
    DESTINATION ${cmake_dir})
  # The API reference (docs/Doxyfile.in) over exactly the installed headers.
  get_property(headers GLOBAL PROPERTY FABRIK_PUBLIC_HEADERS)
  list(APPEND headers ${generated}/fabrik/version.hpp)
  string(REPLACE ";" " " FABRIK_API_INPUT "${headers}")
  set(FABRIK_API_OUTPUT ${PROJECT_BINARY_DIR}/api)
  configure_file(${PROJECT_SOURCE_DIR}/docs/Doxyfile.in ${PROJECT_BINARY_DIR}/Doxyfile @ONLY)
  # The templates, models and example configs, for `fabrik calibrate --template` from an install.
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/config/ DESTINATION ${CMAKE_INSTALL_DATADIR}/fabrik/config)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/proto/ DESTINATION ${CMAKE_INSTALL_DATADIR}/fabrik/proto)
endfunction()
