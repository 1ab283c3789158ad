# Script mode: writes OUT, a C++ file defining std::string_view fabrik::embedded::VAR().
file(READ "${IN}" content HEX)
string(LENGTH "${content}" hex_len)
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "'\\\\x\\1'," bytes "${content}")
file(WRITE "${OUT}"
"// Generated from ${IN}; do not edit.\n#include <string_view>\nnamespace fabrik::embedded {\nstatic const char data_${VAR}[] = {${bytes} 0};\nstd::string_view ${VAR}() { return {data_${VAR}, sizeof(data_${VAR}) - 1}; }\n}  // namespace fabrik::embedded\n")
