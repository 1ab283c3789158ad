// A vendor source's frames as fabrikd's own `markers` messages: the server's
// names with the subject prefix taken off, its positions rotated from its
// axes into the model's lab axes, in millimetres. The message then takes
// the same path as one from the ZeroMQ input (decoding, plausibility,
// occlusion, stats).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <unordered_set>
#include <vector>

#include "config/source_config.hpp"
#include "solver/model.hpp"

namespace fabrik::wire {

// "Subject:LASI" with "*" -> "LASI"; with "Subject:" or "Subject" -> "LASI"; with "" unchanged.
// A prefix that does not end in ASCII punctuation is a subject's name and ends at a colon
// ("Subject" leaves "Subject01:LASI" whole). A name without the given prefix is kept whole (it then
// matches no marker of the model unless the model names it so).
std::string strip_subject_prefix(const std::string& name, const std::string& prefix);

class SourceFrames {
 public:
  // `taken`: the names the daemon's decoder takes (a subject's NAME:Marker among them).
  SourceFrames(const SourceConfig& source, const LabAxes& lab, std::vector<std::string> taken);

  // The server's names for the positions of the frames that follow. A name the daemon
  // takes as it is stays whole (Alice:LASI of a subject Alice, Daphnee:ASISl of a config
  // calibrated from such names). Another loses its subject prefix when that leaves a name
  // the daemon takes, not yet given; else it stays whole (Carol:LASI of a subject another
  // process tracks, a marker the config lacks).
  void labels(std::span<const std::string> server_names);
  // Takes another set of names (a reload changed the config's markers): the server's names
  // read last are mapped again, for the frames that follow.
  void retake(const std::vector<std::string>& taken);
  // The up axis the server states ("+Z", any case; QTM's AxisUpwards). Where the config
  // declares no axes, the server's up is taken, with the lab's forward (or, were that the
  // server's up too, default_forward_lab's): the rotation of the frames that follow. Returns
  // what to tell the user: empty when nothing changed, else how the axes are now taken (or
  // that the config's declared axes disagree with the server's, or that the text is not an axis).
  std::string server_up(std::string_view axis);
  // Server positions to lab positions: the rotation encode() applies.
  const Eigen::Matrix3d& r_lab_server() const { return r_lab_server_; }
  // Encodes one frame (MessagePack, units m: converted once, here, as the
  // decoder converts a ZeroMQ frame's mm) into `payload`. Positions
  // beyond the labels are ignored; labels beyond the positions are sent as missing.
  void encode(std::uint64_t frame_number, double time_s,
              std::span<const Eigen::Vector3d> p_server_mm, std::string& payload);
  const std::vector<std::string>& names() const { return names_; }

 private:
  void map_names();

  std::string prefix_;
  LabAxes lab_;
  std::optional<LabAxes> declared_;  // the config's source_options.axes
  std::string server_up_;            // as last stated, lower case
  std::unordered_set<std::string> taken_;
  std::vector<std::string> server_names_;
  Eigen::Matrix3d r_lab_server_;
  Eigen::Matrix3d r_configured_;  // from the config alone, before the server states an axis
  std::vector<std::string> names_;
  std::vector<Eigen::Vector3d> p_lab_m_;
  std::vector<std::uint8_t> visible_;
};

}  // namespace fabrik::wire
