# locforge_add_plugin(<name> SOURCES <files...> [LINK <targets...>] [NO_INSTALL])
#
# Builds a locforge plugin: a MODULE library exporting only
# `locforge_plugin_entry`, linked to the SDK, placed where the host finds it
# (the build's plugin folder in-tree, or LOCFORGE_PLUGIN_OUTPUT_DIR when set by
# an out-of-tree project) and installed into lib/locforge/plugins.
#
# Used in-tree (include(LocforgePlugin)) and by out-of-tree projects through
# find_package(locforge), which defines the same function and the imported
# target locforge::sdk.
function(locforge_add_plugin name)
  cmake_parse_arguments(ARG "NO_INSTALL" "" "SOURCES;LINK" ${ARGN})
  if(ARG_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "locforge_add_plugin(${name}): unexpected arguments ${ARG_UNPARSED_ARGUMENTS}")
  endif()
  if(NOT ARG_SOURCES)
    message(FATAL_ERROR "locforge_add_plugin(${name}): SOURCES is required")
  endif()
  add_library(${name} MODULE ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE locforge::sdk ${ARG_LINK})
  # The SDK headers need C++17 (std::filesystem, if constexpr).
  target_compile_features(${name} PRIVATE cxx_std_17)
  # Hide everything but the entry point: plugins must not clash with each other.
  set_target_properties(${name} PROPERTIES
    PREFIX "lib"
    CXX_VISIBILITY_PRESET hidden
    C_VISIBILITY_PRESET hidden
    VISIBILITY_INLINES_HIDDEN ON)
  if(LOCFORGE_PLUGIN_OUTPUT_DIR)
    set_target_properties(${name} PROPERTIES LIBRARY_OUTPUT_DIRECTORY "${LOCFORGE_PLUGIN_OUTPUT_DIR}")
  endif()
  # Installed into <libdir>/locforge/plugins: the SDK libraries are two folders
  # up in the same prefix, or (out of tree) in the prefix locforge was found in.
  set(rpath "$ORIGIN/../..")
  if(LOCFORGE_LIBRARY_DIR)
    list(APPEND rpath "${LOCFORGE_LIBRARY_DIR}")
  endif()
  set_target_properties(${name} PROPERTIES INSTALL_RPATH "${rpath}")
  if(NOT ARG_NO_INSTALL)
    set(destination "${LOCFORGE_PLUGIN_INSTALL_DIR}")
    if(NOT destination)
      set(destination "lib/locforge/plugins")
    endif()
    install(TARGETS ${name} LIBRARY DESTINATION "${destination}")
  endif()
endfunction()
