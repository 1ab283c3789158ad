// Levenshtein distance between two names, for "did you mean" suggestions (config fields, marker
// names).
#pragma once

#include <algorithm>
#include <cstddef>
#include <string_view>
#include <vector>

namespace fabrik {

// Levenshtein's distance, or with `swap_is_one_edit` the optimal-string-alignment distance:
// two neighbours swapped are one edit (a typo's distance: "tpc" is one from "tcp", not two).
// Keeps two rows besides the current one.
inline std::size_t edit_distance(std::string_view a, std::string_view b,
                                 bool swap_is_one_edit = false) {
  std::vector<std::size_t> before(b.size() + 1), last(b.size() + 1), row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) last[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      row[j] =
          std::min({last[j] + 1, row[j - 1] + 1, last[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (swap_is_one_edit && i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        row[j] = std::min(row[j], before[j - 2] + 1);
    }
    before.swap(last);
    last.swap(row);
  }
  return last[b.size()];
}

inline std::size_t typo_distance(std::string_view a, std::string_view b) {
  return edit_distance(a, b, true);
}

}  // namespace fabrik
