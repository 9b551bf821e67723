# horizon_add_plugin(<target> SOURCES <src>... [OUTPUT_DIR <dir>] [LINK <libs>...])
#
# Builds a loadable Horizon plugin: a MODULE library named <target>.so
# (no "lib" prefix), C11/C++20, hidden visibility, exporting only the
# entry symbol (version script), linked with -z defs so that an undefined
# symbol is a link error rather than a crash at load time.
#
# Used both by the Horizon tree itself and, through find_package(HorizonSDK),
# by third-party plugin projects.
include_guard(GLOBAL)

set(_HORIZON_PLUGIN_CMAKE_DIR "${CMAKE_CURRENT_LIST_DIR}" CACHE INTERNAL "directory of HorizonPlugin.cmake")

function(horizon_add_plugin target)
  cmake_parse_arguments(HZP "" "OUTPUT_DIR" "SOURCES;LINK" ${ARGN})
  if(NOT HZP_SOURCES)
    message(FATAL_ERROR "horizon_add_plugin(${target}): SOURCES is required")
  endif()
  add_library(${target} MODULE ${HZP_SOURCES})
  # libm is linked for C plugins: -z defs would otherwise reject sqrt() &co.
  target_link_libraries(${target} PRIVATE HorizonSDK::sdk ${HZP_LINK} $<$<PLATFORM_ID:Linux>:m>)
  set_target_properties(${target} PROPERTIES
    PREFIX ""
    C_STANDARD 11 C_STANDARD_REQUIRED ON
    CXX_STANDARD 20 CXX_STANDARD_REQUIRED ON
    C_VISIBILITY_PRESET hidden
    CXX_VISIBILITY_PRESET hidden
    VISIBILITY_INLINES_HIDDEN ON)
  target_link_options(${target} PRIVATE
    "LINKER:--version-script=${_HORIZON_PLUGIN_CMAKE_DIR}/horizon_plugin.version"
    "LINKER:-z,defs")
  if(HZP_OUTPUT_DIR)
    set_target_properties(${target} PROPERTIES LIBRARY_OUTPUT_DIRECTORY "${HZP_OUTPUT_DIR}")
  endif()
endfunction()
