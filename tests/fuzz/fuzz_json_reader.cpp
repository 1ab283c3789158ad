// Our JSON reader (src/transport/json_sax_reader.hpp) against
// nlohmann::json::accept on the same bytes. They must agree, with two
// documented exceptions (docs/fuzzing.md, "NUL bytes after a frame"):
//   - NUL bytes: nlohmann's lexer takes '\0' for the end of the input and
//     ignores whatever follows; our reader takes the payload's length, as
//     ZeroMQ gives it, and rejects a NUL (RFC 8259 allows none outside
//     strings, and none unescaped inside). So with a NUL in the input ours
//     rejects, and ours on the bytes before the first NUL gives nlohmann's verdict.
//   - Nesting deeper than 512 (our reader's bound on its recursion).
// Anything else is a mismatch and aborts.
#include <algorithm>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "fuzz_check.hpp"
#include "transport/json_sax_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using fabrik::fuzz::require;
  static fabrik::wire::JsonSaxReader reader;
  // The handler nlohmann's own accept() drives: every event accepted.
  nlohmann::detail::json_sax_acceptor<nlohmann::json> sax;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const bool ours = reader.parse(text, sax);
  const bool theirs = nlohmann::json::accept(text);
  if (!ours && reader.error().find("nesting too deep") != std::string::npos) {
    require(std::count_if(text.begin(), text.end(), [](char c) { return c == '[' || c == '{'; }) >
                512,
            "our reader says 'nesting too deep' below 513 levels");
    return 0;
  }
  const std::size_t nul = text.find('\0');
  if (nul == std::string_view::npos) {
    if (ours != theirs)
      fabrik::fuzz::fail(ours ? "our JSON reader accepts what nlohmann rejects"
                              : "our JSON reader rejects what nlohmann accepts");
    return 0;
  }
  require(!ours, "our JSON reader accepts a NUL byte");
  const bool ours_before_nul = reader.parse(text.substr(0, nul), sax);
  if (!ours_before_nul && reader.error().find("nesting too deep") != std::string::npos) return 0;
  require(ours_before_nul == theirs,
          "nlohmann's verdict differs from ours on the bytes before the first NUL");
  return 0;
}
