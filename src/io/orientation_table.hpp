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
  // where a cell is not four finite numbers of unit length within 0.01 (empty,
  // "nan", "abc", three or five numbers): missing for that sensor only.
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
  // Whether sample(t_s) reaches a row: t_s within the rows' span or half a sample period
  // (1 us at least) beyond it. False for an empty table or a t_s that is not finite.
  bool covers(double t_s) const;
};

// Read with read_opensim_table (its refusals and warnings apply: a time going
// back is refused, as OpenSim and the TRC reader do); throws FormatError (path
// first) when the file says another DataType than Quaternion or its cells are
// not w,x,y,z. A cell that is not four finite numbers of unit length within
// 0.01 reads as missing for its sensor only, the row kept, with a warning.
OrientationTable read_orientation_table(const std::string& path);

// Joined on time with `trial` (each marker frame takes the table's orientations at its file
// time, OrientationTable::covers): a FormatError (table_path first) when no frame falls within
// the table's span, naming both spans; a warning in `warnings` when some frames do not.
void check_time_overlap(const MarkerTrial& trial, const std::string& trial_path,
                        const OrientationTable& table, const std::string& table_path,
                        std::vector<std::string>& warnings);

// True if the file's name ends in .sto (any case): an OpenSim table rather than markers.
bool is_sto_file(const std::string& path);

}  // namespace fabrik::io
