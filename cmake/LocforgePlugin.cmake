# locforge_add_plugin(<name> SOURCES <files...> [LINK <targets...>] [NO_INSTALL])
#
# Builds a locforge plugin: a MODULE library exporting only
# `locforge_plugin_entry`, linked to the SDK, placed where the host finds it
# (the build's plugin folder in-tree, or LOCFORGE_PLUGIN_OUTPUT_DIR when set by
# an out-of-tree project) and installed into lib/locforge/plugins.
function(locforge_add_plugin name)
  cmake_parse_arguments(ARG "NO_INSTALL" "" "SOURCES;LINK" ${ARGN})
  if(NOT ARG_SOURCES)
    message(FATAL_ERROR "locforge_add_plugin(${name}): SOURCES is required")
  endif()
  add_library(${name} MODULE ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE locforge::sdk ${ARG_LINK})
  # Hide everything but the entry point: plugins must not clash with each other.
  set_target_properties(${name} PROPERTIES
    PREFIX "lib"
    CXX_VISIBILITY_PRESET hidden
    VISIBILITY_INLINES_HIDDEN ON)
  if(LOCFORGE_PLUGIN_OUTPUT_DIR)
    set_target_properties(${name} PROPERTIES LIBRARY_OUTPUT_DIRECTORY "${LOCFORGE_PLUGIN_OUTPUT_DIR}")
  endif()
  if(NOT ARG_NO_INSTALL)
    if(NOT LOCFORGE_PLUGIN_INSTALL_DIR)
      set(LOCFORGE_PLUGIN_INSTALL_DIR "lib/locforge/plugins")
    endif()
    install(TARGETS ${name} LIBRARY DESTINATION "${LOCFORGE_PLUGIN_INSTALL_DIR}")
  endif()
endfunction()
