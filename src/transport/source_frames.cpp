#include "source_frames.hpp"

#include <cctype>
#include <cmath>
#include <iterator>
#include <unordered_set>

#include "config/lab_axes_json.hpp"
#include "config/sensors_json.hpp"
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
      lab_(lab),
      declared_(source.axes),
      taken_(std::make_move_iterator(taken.begin()), std::make_move_iterator(taken.end())),
      r_lab_server_(lab.r_from(server_axes(source, lab))),
      r_configured_(r_lab_server_) {}

std::string SourceFrames::server_up(std::string_view axis) {
  std::string text(axis);
  for (char& ch : text) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (text == server_up_) return {};
  server_up_ = text;
  if (!is_axis_name(text)) {
    r_lab_server_ = r_configured_;
    return "the server states its up axis as '" + std::string(axis) +
           "', which is not an axis: its positions are taken in " +
           (declared_ ? "source_options.axes" : "the model's lab axes");
  }
  const Eigen::Vector3d up = axis_vector(text);
  const std::string up_name = signed_axis_name(up);
  if (declared_) {
    if (declared_->up_lab == up) return {};
    return "the server states its up axis is " + up_name + ", source_options.axes says " +
           signed_axis_name(declared_->up_lab) +
           ": the config's axes are used. Fix: correct source_options.axes, or remove it to take "
           "the server's";
  }
  LabAxes server = lab_;
  server.up_lab = up;
  if (std::abs(lab_.forward_lab.dot(up)) > 0.5) {  // the lab's forward is the server's up axis
    const std::optional<Eigen::Vector3d> forward = default_forward_lab(up);
    if (!forward) {
      r_lab_server_ = r_configured_;
      return "the server's up axis is " + up_name +
             ", the model's lab axes' forward: the "
             "server's forward cannot be told, and its positions are taken as they come. Fix: "
             "state the server's axes in source_options.axes";
    }
    server.forward_lab = *forward;
  }
  const bool was_turned = !r_lab_server_.isIdentity(0.0);
  r_lab_server_ = lab_.r_from(server);
  if (server == lab_)
    return was_turned ? "the server's up axis is now " + up_name +
                            ", the model's lab axes' too: positions are taken as they come"
                      : std::string();
  return "the server's up axis is " + up_name + ", the model's lab axes are " +
         signed_axis_name(lab_.up_lab) + " up: positions are turned from up " + up_name +
         ", forward " + signed_axis_name(server.forward_lab) +
         " into the lab's axes. Set source_options.axes to state the server's forward, or the "
         "model's lab_axes to work in the server's axes";
}

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
