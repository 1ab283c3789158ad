# Where `fabrik view` finds its installed page (`full_page_dir`, under DATADIR), from the folder
# of the `fabrik` it runs as: a path relative to that folder while BINDIR and DATADIR are both
# relative (they move together, cmake --install --prefix included), else the page's absolute
# path at configure time (an absolute DATADIR stays put; under an absolute BINDIR the prefix
# cannot be told from the program's own path). A build tree's `fabrik` then finds an installed
# page there too; its first line says which (`page from DIR`).
function(fabrik_view_page_from_bin out bindir datadir full_bindir full_page_dir)
  if(IS_ABSOLUTE "${bindir}" OR IS_ABSOLUTE "${datadir}")
    set(path "${full_page_dir}")
  else()
    file(RELATIVE_PATH path "${full_bindir}" "${full_page_dir}")
  endif()
  set(${out} "${path}" PARENT_SCOPE)
endfunction()
