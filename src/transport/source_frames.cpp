#include "source_frames.hpp"

#include <cctype>
#include <cmath>
#include <iterator>
#include <unordered_set>

#include "marker_codec.hpp"

namespace fabrik::wire {

std::string strip_subject_prefix(const std::string& name, const std::string& prefix) {
  if (prefix == "*") {
    const std::size_t colon = name.rfind(':');
    return colon == std::string::npos ? name : name.substr(colon + 1);
  }
  if (prefix.empty() || !name.starts_with(prefix)) return name;
  // A prefix ending in a letter or digit is a subject's name: it ends at a colon ("Daphnee"
  // strips "Daphnee:", not "Daphnee" of "Daphnee:ASISl", and "Subject" not "Subject01:").
  // ASCII punctuation ends a prefix; any byte of UTF-8 beyond ASCII is a letter ("Daphné").
  const unsigned char last = static_cast<unsigned char>(prefix.back());
  const bool ascii_punctuation = last < 0x80 && std::ispunct(last) != 0;
  if (ascii_punctuation) return name.substr(prefix.size());
  if (name.size() > prefix.size() && name[prefix.size()] == ':')
    return name.substr(prefix.size() + 1);
  return name;
}

namespace {

LabAxes server_axes(const SourceConfig& source, const LabAxes& lab) {
  if (source.axes) return *source.axes;
  if (source.kind == SourceKind::natnet) return LabAxes{Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitX()};
  return lab;
}

}  // namespace

SourceFrames::SourceFrames(const SourceConfig& source, const LabAxes& lab,
                           std::vector<std::string> taken)
    : prefix_(source.subject_prefix),
      taken_(std::make_move_iterator(taken.begin()), std::make_move_iterator(taken.end())),
      r_lab_server_(lab.r_from(server_axes(source, lab))) {}

void SourceFrames::labels(std::span<const std::string> server_names) {
  server_names_.assign(server_names.begin(), server_names.end());
  map_names();
}

// All or nothing: should an allocation throw, the names taken and their map stay the old ones.
void SourceFrames::retake(const std::vector<std::string>& taken) {
  std::unordered_set<std::string> set(taken.begin(), taken.end());
  taken_.swap(set);
  try {
    map_names();
  } catch (...) {
    taken_.swap(set);
    throw;
  }
}

// Built aside and swapped in: should an allocation throw, the names and the arrays encode()
// indexes by them keep one length.
void SourceFrames::map_names() {
  std::vector<std::string> names;
  names.reserve(server_names_.size());
  // A name is stripped only into one the daemon takes: another process's subject
  // (Carol:LASI beside Alice and Bob) stays whole, so the daemon sees it as another
  // subject's and not as a marker its config lacks. The server's own taken names come first.
  std::unordered_set<std::string> used;
  for (const std::string& name : server_names_)
    if (taken_.contains(name)) used.insert(name);
  for (const std::string& name : server_names_) {
    if (taken_.contains(name)) {
      names.push_back(name);
      continue;
    }
    std::string stripped = strip_subject_prefix(name, prefix_);
    const bool take = taken_.contains(stripped) && used.insert(stripped).second;
    names.push_back(take ? std::move(stripped) : name);
  }
  std::vector<Eigen::Vector3d> p_lab_m(names.size(), Eigen::Vector3d::Zero());
  std::vector<std::uint8_t> visible(names.size(), 0);
  names_.swap(names);
  p_lab_m_.swap(p_lab_m);
  visible_.swap(visible);
}

void SourceFrames::encode(std::uint64_t frame_number, double time_s,
                          std::span<const Eigen::Vector3d> p_server_mm, std::string& payload) {
  for (std::size_t i = 0; i < names_.size(); ++i) {
    const bool seen = i < p_server_mm.size() && p_server_mm[i].allFinite();
    visible_[i] = seen ? 1 : 0;
    p_lab_m_[i] = seen ? Eigen::Vector3d(r_lab_server_ * p_server_mm[i] * 1e-3) : Eigen::Vector3d::Zero();
  }
  encode_marker_frame(frame_number, std::isfinite(time_s) ? &time_s : nullptr, names_, p_lab_m_,
                      visible_, "m", PayloadEncoding::msgpack, payload);
}

}  // namespace fabrik::wire
