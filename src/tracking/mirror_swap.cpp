#include "mirror_swap.hpp"

#include <algorithm>
#include <cmath>
#include <string_view>
#include <utility>

namespace fabrik {

namespace {

// Right/left spellings, tried as a prefix and as a suffix.
constexpr std::pair<std::string_view, std::string_view> kSides[] = {
    {"RIGHT", "LEFT"}, {"Right", "Left"}, {"right", "left"}, {"R", "L"}, {"r", "l"}};

// The left counterpart of a right-side name, or "" when it has no right prefix or suffix.
std::string left_name(const std::string& name, std::string_view right, std::string_view left,
                      bool prefix) {
  if (name.size() <= right.size()) return {};
  if (prefix ? name.starts_with(right) : name.ends_with(right))
    return prefix ? std::string(left) + name.substr(right.size())
                  : name.substr(0, name.size() - right.size()) + std::string(left);
  return {};
}

}  // namespace

std::vector<std::array<int, 2>> mirror_pairs_from_names(const std::vector<std::string>& names) {
  std::vector<std::array<int, 2>> pairs;
  std::vector<std::uint8_t> used(names.size(), 0);
  for (std::size_t r = 0; r < names.size(); ++r) {
    for (const auto& [right, left] : kSides) {
      if (used[r]) break;
      for (const bool prefix : {true, false}) {
        const std::string l = left_name(names[r], right, left, prefix);
        if (l.empty()) continue;
        const auto it = std::find(names.begin(), names.end(), l);
        if (it == names.end()) continue;
        const auto li = static_cast<std::size_t>(it - names.begin());
        if (used[li] || li == r) continue;
        pairs.push_back({static_cast<int>(r), static_cast<int>(li)});
        used[r] = used[li] = 1;
        break;
      }
    }
  }
  return pairs;
}

int marker_in_two_pairs(std::span<const std::array<int, 2>> pairs) {
  for (std::size_t k = 1; k < pairs.size(); ++k)
    for (std::size_t e = 0; e < k; ++e)
      for (const int m : pairs[k])
        if (pairs[e][0] == m || pairs[e][1] == m) return m;
  return -1;
}

MirrorSwap::MirrorSwap(OutlierSettings settings, std::vector<std::array<int, 2>> pairs)
    : settings_(settings), pairs_(std::move(pairs)), since_s_(pairs_.size(), NAN) {}

void MirrorSwap::reset() {
  std::fill(since_s_.begin(), since_s_.end(), NAN);
}

int MirrorSwap::apply(double time_s, std::span<Eigen::Vector3d> measured_m,
                      std::span<const std::uint8_t> seen,
                      std::span<const Eigen::Vector3d> predicted_m,
                      std::span<int> relabelled_from) {
  int swapped = 0;
  for (std::size_t k = 0; k < pairs_.size(); ++k) {
    const auto [r, l] = pairs_[k];
    if (!seen[r] || !seen[l]) continue;  // an unmeasured side neither starts nor ends a stretch
    const double labelled_m =
        (measured_m[r] - predicted_m[r]).norm() + (measured_m[l] - predicted_m[l]).norm();
    const double mirrored_m =
        (measured_m[l] - predicted_m[r]).norm() + (measured_m[r] - predicted_m[l]).norm();
    if (labelled_m <= 2.0 * settings_.mirror_floor_m ||
        mirrored_m >= settings_.mirror_ratio * labelled_m) {
      since_s_[k] = NAN;
      continue;
    }
    if (std::isnan(since_s_[k])) since_s_[k] = time_s;
    // Too long at a stretch (or a clock that went back): the labels stand.
    const double stretch_s = time_s - since_s_[k];
    if (!(stretch_s >= 0.0 && stretch_s <= settings_.mirror_max_s)) continue;
    std::swap(measured_m[r], measured_m[l]);
    relabelled_from[r] = l;
    relabelled_from[l] = r;
    swapped += 2;
  }
  return swapped;
}

}  // namespace fabrik
