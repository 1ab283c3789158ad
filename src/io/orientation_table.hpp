// OpenSim orientation tables: the quaternion .sto files OpenSense reads and
// writes (version 3: `key=value` header lines such as DataRate and
// DataType=Quaternion up to `endheader`, a tab-separated label line `time`
// plus one column per sensor, then one row per sample whose cells are
// `w,x,y,z`). Read for tracking (`fabrik solve --orientations`, `fabrik
// replay --orientations`, `fabrik calibrate --static-orientations`).
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

namespace fabrik::io {

struct OrientationTable {
  std::vector<std::string> sensors;  // column labels after time
  std::vector<double> time_s;        // per row, increasing
  // Row-major, [row * sensors.size() + k], as written (w, x, y, z); all NaN
  // where a cell is empty, "nan" or not four numbers.
  std::vector<Eigen::Quaterniond> q;
  double rate_hz = 0.0;     // DataRate, else from the time column
  std::string rate_source;  // "from DataRate", "from the time column", "" when unknown
  // What the reader noticed and worked around, one sentence each.
  std::vector<std::string> warnings;

  std::size_t rows() const { return time_s.size(); }
  const Eigen::Quaterniond& at(std::size_t row, std::size_t sensor) const {
    return q[row * sensors.size() + sensor];
  }
  int find(const std::string& sensor) const;  // -1 if absent
  // Orientations at time t (out has one per sensor): the spherical
  // interpolation of the two rows around t (a row's own values when t is
  // within 1 us of it), NaN where either is missing; the end row's within half
  // a sample period beyond the first or last row, NaN farther out.
  void sample(double t_s, std::span<Eigen::Quaterniond> out) const;
};

// Read with read_opensim_table (its refusals and warnings apply); throws
// FormatError (path first) when the file says another DataType than
// Quaternion or its cells are not w,x,y,z. Quaternions that are not finite or
// not unit within 0.01 read as missing, with a warning.
OrientationTable read_orientation_table(const std::string& path);

// True if the file's name ends in .sto (any case): an OpenSim table rather than markers.
bool is_sto_file(const std::string& path);

}  // namespace fabrik::io
