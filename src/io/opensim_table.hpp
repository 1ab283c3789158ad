/// @file
/// OpenSim's tables (.sto storage files and .mot motion files, versions 1 and
/// 3): header lines up to `endheader` (version 1: a name line, then `key=value`
/// lines such as version, nRows, nColumns, inDegrees, and free text; version 3:
/// `key=value` lines such as DataRate and DataType), then a tab-separated table
/// whose first column is time. Cells are numbers, or comma-separated tuples such
/// as the quaternions `w,x,y,z` of OpenSense orientation files. Read to say what
/// a file holds (`fabrik info`) and to use its values (`fabrik eval angles`);
/// written for `fabrik solve --angles`. Values stay as the file has them
/// (degrees stay degrees: see in_degrees()).
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace fabrik::io {

/// One OpenSim table as read or to be written (see the file's description).
struct OpenSimTable {
  std::string name;                                         ///< the header's first line, if not key=value
  std::vector<std::pair<std::string, std::string>> header;  ///< key=value lines, in order
  std::vector<std::string> comments;                        ///< the header's other lines
  std::vector<std::string> columns;                         ///< the labels, time first
  std::size_t rows = 0;  ///< rows of the table (time_s.size())
  /// Time of the first row, seconds.
  double first_time_s = 0.0, last_time_s = 0.0;
  /// @var last_time_s
  /// Time of the last row, seconds.
  double rate_hz = 0.0;     ///< DataRate, else from the time column (rows - 1 over the span)
  std::string rate_source;  ///< "from DataRate", "from the time column", "" when unknown
  std::string cell_kind;    ///< "numbers", or "quaternions (w,x,y,z)" / "3-vectors" when cells
                            // hold comma-separated tuples
  std::size_t cell_width = 1;  ///< numbers per cell
  /// Cells not of cell_width numbers, read as missing (ReadTableOptions::bad_cells_missing).
  std::size_t bad_cells = 0;
  /// Rows with a different number of fields, nRows/nColumns that disagree with the table, ...
  std::vector<std::string> warnings;
  std::vector<double> time_s;  ///< per row
  std::vector<double> values;  ///< per row, per column after time, cell_width numbers each

  /// Index of the column named `label` in `columns` (time is 0), -1 if absent.
  int find(const std::string& label) const;
  /// The header value of `key` ("" if absent).
  std::string header_value(const std::string& key) const;
  /// inDegrees=yes (Coordinates files): rotational columns are in degrees.
  bool in_degrees() const;
  /// Number k of the cell of `row` in `column` (an index into `columns`, >= 1).
  double at(std::size_t row, std::size_t column, std::size_t k = 0) const {
    return values[(row * (columns.size() - 1) + column - 1) * cell_width + k];
  }
  /// A quaternion cell (cell_width 4, stored w, x, y, z).
  Eigen::Quaterniond quaternion(std::size_t row, std::size_t column) const;
  /// Appends a row: `cells` holds (columns.size() - 1) * cell_width numbers.
  void add_row(double time, const std::vector<double>& cells);
};

/// An empty OpenSim Coordinates table (version 1, nRows, nColumns, inDegrees)
/// with these columns after time, as OpenSim's inverse kinematics writes it.
OpenSimTable coordinates_table(const std::vector<std::string>& labels, bool in_degrees);

/// How read_opensim_table reads rows that OpenSim would not.
struct OpenSimReadOptions {
  /// A cell that is not numbers of the table's width is NaN, its row kept (a dropout of one
  /// sensor in an orientation table); false: the row is left out.
  bool bad_cells_missing = false;
  /// A time before the previous row's is a FormatError, as OpenSim refuses it; false: a warning
  /// (to describe the file, `fabrik info`).
  bool refuse_time_back = true;
};

/// Throws FormatError (path first) when there is no `endheader` or no table
/// after it, or (see OpenSimReadOptions) a time goes back. Rows that cannot be
/// used (a different number of fields, no time, a cell that is not a number or
/// has another width than the first row's) are left out and said in
/// `warnings`, as are times equal to the previous row's and nRows/nColumns
/// that disagree with the table.
OpenSimTable read_opensim_table(const std::string& path, const OpenSimReadOptions& options = {});

/// Writes the table: the name line, the header (nRows and nColumns from the
/// table), the comments, `endheader`, the labels, one tab-separated row per
/// time. Throws FormatError if the file cannot be written and
/// std::invalid_argument if the table is inconsistent (sizes, labels with
/// tabs, commas or line breaks).
void write_opensim_table(const std::string& path, const OpenSimTable& table);

}  // namespace fabrik::io
