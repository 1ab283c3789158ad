// Which names come closest to a config's marker names, when a recording or a stream does not
// use them: the same name in another case, after a `Subject:` prefix, with other punctuation,
// or within a few edits. Shared by `fabrik solve` (refusing a trial) and fabrikd (warning
// about a stream).
#pragma once

#include <string>
#include <vector>

namespace fabrik {

struct NameMatch {
  std::string config_name;
  std::string trial_label;
  std::string how;  // "case", "after 'Subject:'", "without 'Subject:'", "punctuation", "2 edits"
  // Where the two differ by a `Subject:` prefix only: the label's ("Sub:") and the name's.
  std::string label_prefix, name_prefix;
};

// For each config name, the label closest to it, if any is close: the same name in another
// case, the same name after a `Subject:` prefix, or a spelling within a few edits (ignoring
// case and punctuation). Best matches first.
std::vector<NameMatch> closest_labels(const std::vector<std::string>& config_names,
                                      const std::vector<std::string>& trial_labels);

// "A, B, C, ... (N in all)": at most `at_most` names.
std::string name_list(const std::vector<std::string>& names, std::size_t at_most);

// The config's names beside the other side's, and the closest matches:
//   "\n  config: ...\n  <other_title> ...\n  closest: A ~ a (case), ..."
// `other_title` is padded by the caller ("file:  ", "stream:").
std::string names_beside(const std::vector<std::string>& config_names,
                         const std::string& other_title, const std::vector<std::string>& others);

}  // namespace fabrik
