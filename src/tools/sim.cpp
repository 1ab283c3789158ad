#include "sim.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "replay.hpp"

namespace fabrik::tools {

namespace {

std::int64_t frame_at(double t_s, const bridges::SimRecording& r) {
  return static_cast<std::int64_t>(std::llround(t_s * r.rate_hz));
}

// "A:B" split at the first colon.
std::pair<std::string, std::string> split_at_colon(const std::string& spec, const std::string& option,
                                                   const char* expected) {
  const std::size_t c = spec.find(':');
  if (c == std::string::npos)
    throw std::invalid_argument(option + " '" + spec + "': expected " + expected);
  return {spec.substr(0, c), spec.substr(c + 1)};
}

}  // namespace

bridges::SimRecording sim_recording(const io::MarkerTrial& trial, const std::string& file_up) {
  if (trial.frames() == 0 || trial.markers() == 0)
    throw std::invalid_argument("the recording has no marker frames");
  if (!(trial.rate_hz > 0.0)) throw std::invalid_argument("the recording has no frame rate");
  bridges::SimRecording r;
  r.rate_hz = trial.rate_hz;
  r.names = trial.labels;
  r.up = !file_up.empty() ? file_up : trial.source.format == "TRC" ? "+y" : "+z";
  r.p_mm.resize(trial.frames());
  for (std::size_t f = 0; f < trial.frames(); ++f) {
    r.p_mm[f].resize(trial.markers());
    for (std::size_t m = 0; m < trial.markers(); ++m) {
      const Eigen::Vector3d& p_m = trial.at(f, m);
      r.p_mm[f][m] = p_m.allFinite() ? Eigen::Vector3d(p_m * 1000.0)
                                     : Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    }
  }
  return r;
}

bridges::SimScript sim_script(const SimScriptArgs& args, const bridges::SimRecording& recording) {
  bridges::SimScript s;
  for (const std::string& spec : args.pauses) {
    const auto [t, d] = split_at_colon(spec, "--pause-at", "T:S (time and seconds to pause)");
    s.pauses.push_back({frame_at(parse_seconds_field(t, "--pause-at", spec, "T", "T:S"), recording),
                        parse_seconds_field(d, "--pause-at", spec, "S", "T:S")});
  }
  for (const std::string& spec : args.restarts) {
    const auto [t, d] = split_at_colon(spec, "--restart-at", "T:S (time and seconds down)");
    s.restarts.push_back({frame_at(parse_seconds_field(t, "--restart-at", spec, "T", "T:S"), recording),
                          parse_seconds_field(d, "--restart-at", spec, "S", "T:S")});
  }
  for (const std::string& spec : args.renames) {
    const auto [t, change] = split_at_colon(spec, "--rename-at", "T:OLD=NEW");
    const std::size_t eq = change.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == change.size())
      throw std::invalid_argument("--rename-at '" + spec + "': expected T:OLD=NEW (two marker names)");
    const std::string from = change.substr(0, eq), to = change.substr(eq + 1);
    bool known = false;
    for (const std::string& n : recording.names) known = known || n == from;
    if (!known) throw std::invalid_argument("--rename-at '" + spec + "': the recording has no marker '" + from + "'");
    s.renames.push_back({frame_at(parse_seconds_field(t, "--rename-at", spec, "T", "T:OLD=NEW"), recording), from, to});
  }
  for (const std::string& spec : args.drops) {
    const DropSpec d = parse_drop_spec(spec);
    bool known = false;
    for (const std::string& n : recording.names) known = known || n == d.marker;
    if (!known) throw std::invalid_argument("--drop '" + spec + "': the recording has no marker '" + d.marker + "'");
    s.drops.push_back({d.marker, frame_at(d.t0_s, recording), frame_at(d.t1_s, recording)});
  }
  return s;
}

}  // namespace fabrik::tools
