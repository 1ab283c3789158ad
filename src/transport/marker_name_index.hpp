// Marker (or sensor) name -> tracker index for the decoder's hot path,
// looked up by std::string_view so no std::string is made per key. A source
// sends the same names in the same order frame after frame, so `find_at`
// first tries the name the previous frame had at that position (one length
// check and one memcmp), then an open-addressing hash table (FNV-1a).
// Never allocates after construction.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fabrik::wire {

class MarkerNameIndex {
 public:
  // Duplicate names: the first one's index is kept (as std::unordered_map::emplace).
  explicit MarkerNameIndex(std::span<const std::string> names) : names_(names.begin(), names.end()) {
    std::size_t slots = 8;
    while (slots < 2 * names_.size()) slots *= 2;  // at most half full: short probes
    slots_.assign(slots, -1);
    mask_ = slots - 1;
    for (int i = 0; i < static_cast<int>(names_.size()); ++i)
      if (find(names_[i]) < 0) slots_[probe_for(names_[i])] = i;
    previous_.assign(names_.size() + kExtraPositions, -1);
    for (const std::string& n : names_) {
      const std::size_t colon = n.find(':');
      if (colon == std::string::npos || colon == 0) continue;
      const std::string_view prefix(n.data(), colon + 1);
      if (std::find(prefixes_.begin(), prefixes_.end(), prefix) == prefixes_.end())
        prefixes_.emplace_back(prefix);
    }
  }

  // Whether `name` is "X:..." and no name of the index starts "X:": another subject's, when
  // the index holds subjects' names (NAME:Marker).
  bool foreign(std::string_view name) const {
    const std::size_t colon = name.find(':');
    if (colon == std::string_view::npos || colon == 0) return false;
    return std::find(prefixes_.begin(), prefixes_.end(), name.substr(0, colon + 1)) ==
           prefixes_.end();
  }

  // Whether the names are a multi-subject config's (SUBJECT:Marker for each listed subject):
  // another subject's unknown names are then listed once per subject (see count_marker).
  bool of_subjects() const { return of_subjects_; }
  void set_of_subjects(bool on) { of_subjects_ = on; }

  // The name's index, or -1 when it is none of the names.
  int find(std::string_view name) const { return slots_[probe_for(name)]; }

  // The index of the name at `position` among a frame's names (0, 1, ...):
  // the previous frame's name at that position is tried first.
  int find_at(std::size_t position, std::string_view name) {
    if (position < previous_.size()) {
      const int hint = previous_[position];
      if (hint >= 0 && names_[hint] == name) return hint;
    }
    const int found = find(name);
    if (position < previous_.size()) previous_[position] = found;
    return found;
  }

 private:
  // Room for a few names beyond the model's (unknown markers) in the hints.
  static constexpr std::size_t kExtraPositions = 16;

  static std::uint64_t hash(std::string_view s) {
    std::uint64_t h = 14695981039346656037ull;
    for (const char c : s) h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ull;
    return h;
  }
  // The slot holding `name`, or the empty slot where it would go.
  std::size_t probe_for(std::string_view name) const {
    std::size_t slot = hash(name) & mask_;
    while (slots_[slot] >= 0 && names_[slots_[slot]] != name) slot = (slot + 1) & mask_;
    return slot;
  }

  std::vector<std::string> names_;
  std::vector<int> slots_;  // index into names_, -1 empty
  std::size_t mask_ = 0;
  std::vector<int> previous_;  // the index (or -1) of the name at each position of the last frame
  std::vector<std::string> prefixes_;  // the names' distinct "X:" (subjects' prefixes)
  bool of_subjects_ = false;           // see of_subjects()
};

}  // namespace fabrik::wire
