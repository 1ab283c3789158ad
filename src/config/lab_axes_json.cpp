#include "lab_axes_json.hpp"

#include <cmath>

#include "sensors_json.hpp"

namespace fabrik {

namespace {

Eigen::Vector3d read_axis(const JsonReader& r) {
  const std::string name = r.as_string();
  if (!is_axis_name(name))
    r.fail("'" + name + "' is not an axis",
           "write \"x\", \"y\" or \"z\", optionally with a sign (\"+z\", \"-y\")");
  return axis_vector(name);
}

}  // namespace

LabAxesSpec read_lab_axes(const JsonReader& r) {
  r.expect_object();
  r.only_keys({"up", "forward", "description"});
  LabAxesSpec spec;
  spec.up_lab = read_axis(r.at("up"));
  if (r.has("forward")) {
    spec.forward_lab = read_axis(r.at("forward"));
    if (std::abs(spec.up_lab.dot(*spec.forward_lab)) > 0.5)
      r.at("forward").fail("forward is along the up axis",
                           "name a horizontal lab axis: one of the two that are not up");
  }
  return spec;
}

LabAxes read_whole_lab_axes(const JsonReader& r, const std::string& problem, const std::string& fix) {
  const LabAxesSpec spec = read_lab_axes(r);
  const std::optional<Eigen::Vector3d> forward =
      spec.forward_lab ? spec.forward_lab : default_forward_lab(spec.up_lab);
  if (!forward) r.fail(problem, fix);
  return LabAxes{spec.up_lab, *forward};
}

std::optional<Eigen::Vector3d> default_forward_lab(const Eigen::Vector3d& up_lab) {
  if (std::abs(up_lab.x()) > 0.5) return std::nullopt;
  return Eigen::Vector3d::UnitX();
}

std::string signed_axis_name(const Eigen::Vector3d& axis) {
  int k = 0;
  axis.cwiseAbs().maxCoeff(&k);
  return std::string(axis[k] < 0.0 ? "-" : "+") + "xyz"[k];
}

nlohmann::ordered_json lab_axes_json(const LabAxes& axes) {
  return {{"up", signed_axis_name(axes.up_lab)}, {"forward", signed_axis_name(axes.forward_lab)}};
}

}  // namespace fabrik
