// "lab_axes" of models and templates (docs/lab-axes.md): which of the
// lab's axes is up and which is forward, as signed axis names,
// {"up": "+z", "forward": "+x"}. They turn world-relative coordinates into
// OpenSim's ground frame (X forward, Y up, Z right: LabAxes in
// solver/model.hpp); positions stay in the lab's frame.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "json_reader.hpp"
#include "solver/model.hpp"

namespace fabrik {

// As written: `forward` may be absent (a template leaves it to calibration).
struct LabAxesSpec {
  Eigen::Vector3d up_lab{0, 1, 0};
  std::optional<Eigen::Vector3d> forward_lab;
};

// Reads {"up": AXIS, "forward": AXIS}; AXIS is "x", "y" or "z" with an
// optional sign. Up and forward must be different lab axes.
LabAxesSpec read_lab_axes(const JsonReader& r);
// The same, whole: an absent forward is default_forward_lab's; with x up and
// none, fails with `problem` and `fix`.
LabAxes read_whole_lab_axes(const JsonReader& r, const std::string& problem, const std::string& fix);

// The forward axis when none is declared: +x while x is horizontal (up is y
// or z), so a lab with X forward keeps its numbers. Empty when up is along x:
// then forward has to be declared or detected.
std::optional<Eigen::Vector3d> default_forward_lab(const Eigen::Vector3d& up_lab);

// A principal unit axis as its signed name, "+z", "-y".
std::string signed_axis_name(const Eigen::Vector3d& axis);

// {"up": "+z", "forward": "+x"}
nlohmann::ordered_json lab_axes_json(const LabAxes& axes);

}  // namespace fabrik
