# Where `fabrik view` finds its installed page, from the folder of the `fabrik` it runs as:
# a path relative to that folder while BINDIR and DATADIR are both relative (they move
# together, cmake --install --prefix included), else DATADIR's absolute path at configure
# time (an absolute DATADIR stays put; under an absolute BINDIR the prefix cannot be told
# from the program's own path).
function(fabrik_view_page_from_bin out bindir datadir full_bindir full_datadir)
  if(IS_ABSOLUTE "${bindir}" OR IS_ABSOLUTE "${datadir}")
    set(path "${full_datadir}/fabrik/view")
  else()
    file(RELATIVE_PATH path "${full_bindir}" "${full_datadir}/fabrik/view")
  endif()
  set(${out} "${path}" PARENT_SCOPE)
endfunction()
