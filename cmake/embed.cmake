# fabrik_embed(TARGET VAR FILE): compiles FILE's text into TARGET as
# `std::string_view VAR()` so the executables work from any directory.
function(fabrik_embed target var file)
  set(out_cpp "${CMAKE_CURRENT_BINARY_DIR}/embedded_${var}.cpp")
  add_custom_command(
    OUTPUT "${out_cpp}"
    COMMAND ${CMAKE_COMMAND} -DIN=${file} -DOUT=${out_cpp} -DVAR=${var}
            -P "${PROJECT_SOURCE_DIR}/cmake/embed_file.cmake"
    DEPENDS "${file}" "${PROJECT_SOURCE_DIR}/cmake/embed_file.cmake"
    COMMENT "Embedding ${file}")
  target_sources(${target} PRIVATE "${out_cpp}")
endfunction()
