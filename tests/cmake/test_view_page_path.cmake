# cmake -P: where `fabrik view` looks for its installed page (cmake/view_page_path.cmake) for
# each kind of BINDIR and DATADIR; exits non-zero on the first wrong answer.
include(${CMAKE_CURRENT_LIST_DIR}/../../cmake/view_page_path.cmake)

function(expect bindir datadir full_bindir full_datadir want)
  fabrik_view_page_from_bin(got "${bindir}" "${datadir}" "${full_bindir}"
    "${full_datadir}/fabrik/view")
  if(NOT got STREQUAL want)
    message(FATAL_ERROR "BINDIR ${bindir}, DATADIR ${datadir}: '${got}', expected '${want}'")
  endif()
endfunction()

# Both relative: found from the program's folder wherever the prefix is (--prefix at install).
expect(bin share /usr/local/bin /usr/local/share ../share/fabrik/view)
expect(libexec/fabrik/bin share /opt/f/libexec/fabrik/bin /opt/f/share ../../../share/fabrik/view)
# An absolute DATADIR stays where it is: the page too.
expect(bin /srv/share /usr/local/bin /srv/share /srv/share/fabrik/view)
# An absolute BINDIR: the prefix cannot be told from the program's path; DATADIR as configured.
expect(/opt/bin share /opt/bin /usr/local/share /usr/local/share/fabrik/view)
message(STATUS "view page path: 4 layouts right")
