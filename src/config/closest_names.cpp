#include "config/closest_names.hpp"

#include <algorithm>
#include <cctype>
#include <optional>

#include "common/ascii_case.hpp"
#include "common/edit_distance.hpp"

namespace fabrik {

namespace {

// Lower case, letters and digits only: "R.ASIS" and "r_asis" both become "rasis".
std::string normalized(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (std::isalnum(static_cast<unsigned char>(c))) {
      out += ascii_lower(c);
    }
  }
  return out;
}

// The label after a `Subject:` prefix (Vicon), or the label itself.
std::string without_prefix(const std::string& label) {
  const std::size_t colon = label.rfind(':');
  return colon == std::string::npos ? label : label.substr(colon + 1);
}

}  // namespace

std::string name_list(const std::vector<std::string>& names, std::size_t at_most) {
  std::string out;
  for (std::size_t i = 0; i < names.size() && i < at_most; ++i) {
    out += (i > 0 ? ", " : "") + names[i];
  }
  if (names.size() > at_most) out += ", ... (" + std::to_string(names.size()) + " in all)";
  return out;
}

std::vector<NameMatch> closest_labels(const std::vector<std::string>& config_names,
                                      const std::vector<std::string>& trial_labels) {
  struct Scored {
    NameMatch match;
    std::size_t score;  // lower is closer
  };
  std::vector<Scored> found;
  for (const std::string& name : config_names) {
    std::optional<Scored> best;
    const auto offer = [&](const std::string& label, std::string how, std::size_t score,
                           std::string label_prefix = {}, std::string name_prefix = {}) {
      if (!best || score < best->score)
        best = Scored{
            {name, label, std::move(how), std::move(label_prefix), std::move(name_prefix)}, score};
    };
    // A config calibrated from one subject of a Nexus file names its markers `Subject:Marker`;
    // its subject's own export may not.
    const std::string bare_name = without_prefix(name);
    const std::string name_prefix = name.substr(0, name.size() - bare_name.size());
    for (const std::string& label : trial_labels) {
      const std::string bare = without_prefix(label);
      const std::string prefix = label.substr(0, label.size() - bare.size());
      if (iequals(label, name)) {
        offer(label, "case", 0);
      } else if (bare != label && iequals(bare, name)) {
        offer(label, "after '" + prefix + "'", 1, prefix);
      } else if (!name_prefix.empty() && iequals(bare, bare_name)) {
        offer(label,
              prefix.empty() ? "without '" + name_prefix + "'"
                             : "after '" + prefix + "', not '" + name_prefix + "'",
              1, prefix, name_prefix);
      } else {
        const std::string a = normalized(name), b = normalized(bare);
        if (a.empty() || b.empty()) continue;
        const std::size_t d = edit_distance(a, b);
        // A few edits for names long enough that a few edits leave most of them.
        if (d <= std::max<std::size_t>(1, std::min(a.size(), b.size()) / 3)) {
          // Ties go to the label with the same first letter (the side, in most marker sets).
          offer(label, d == 0 ? "punctuation" : std::to_string(d) + (d == 1 ? " edit" : " edits"),
                2 + 2 * d + (a[0] == b[0] ? 0 : 1));
        }
      }
    }
    if (best) found.push_back(*best);
  }
  std::stable_sort(found.begin(), found.end(),
                   [](const Scored& a, const Scored& b) { return a.score < b.score; });
  std::vector<NameMatch> out;
  for (Scored& s : found) out.push_back(std::move(s.match));
  return out;
}

std::string names_beside(const std::vector<std::string>& config_names,
                         const std::string& other_title, const std::vector<std::string>& others) {
  std::string text =
      "\n  config: " + name_list(config_names, 12) + "\n  " + other_title + " " + name_list(others, 12);
  const std::vector<NameMatch> close = closest_labels(config_names, others);
  if (!close.empty()) {
    text += "\n  closest:";
    for (std::size_t i = 0; i < close.size() && i < 8; ++i) {
      text += (i > 0 ? ", " : " ") + close[i].config_name + " ~ " + close[i].trial_label + " (" +
              close[i].how + ")";
    }
    if (close.size() > 8) text += ", ... (" + std::to_string(close.size()) + " in all)";
  }
  return text;
}

}  // namespace fabrik
