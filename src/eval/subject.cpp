#include "subject.hpp"

#include "calib/calibrate.hpp"

namespace fabrik::eval {

DaemonConfig calibrate_config(const std::string& template_path, const std::string& static_path) {
  const calib::CalibTemplate tmpl = calib::load_template_file(template_path);
  const io::MarkerTrial trial = io::read_trial(static_path);
  const calib::CalibrationResult r = calib::calibrate(tmpl, trial, static_path);
  return load_daemon_config(r.config.dump(), "<calibrated from " + static_path + ">");
}

ReferencePoints reference_points(const Model& model) {
  ReferencePoints refs;
  auto add = [&](int p) {
    const std::string& name = model.points[p].name;
    refs.points.push_back(p);
    refs.names.push_back(name);
    const bool sided = name.size() > 2 && (name[0] == 'r' || name[0] == 'l') && name[1] == '_';
    refs.groups.push_back(sided ? name.substr(2) : name);
  };
  for (const Joint& j : model.joints) add(j.point);
  for (std::size_t p = 0; p < model.points.size(); ++p)
    if (model.points[p].kind == PointKind::end_site) add(static_cast<int>(p));
  return refs;
}

std::vector<int> trial_columns(const DaemonConfig& config, const io::MarkerTrial& trial) {
  std::vector<int> c;
  for (const MarkerTarget& m : config.tracker.markers) c.push_back(trial.find(m.marker));
  return c;
}

}  // namespace fabrik::eval
