// Marker trials across the Python edge (recordings.cpp), shared with the whole-trial solve.
#pragma once

#include "bindings.hpp"
#include "io/marker_trial.hpp"

namespace fabrik::python {

// names, positions_mm (frames, markers, 3; NaN where missing), time_s (the file's times),
// frame_numbers, rate_hz, first_frame, file_units, format, warnings. Moves the positions.
py::dict marker_trial_dict(io::MarkerTrial&& trial);
// A .trc or .c3d file with 3D markers (FormatError otherwise). Needs no GIL: call
// require_file first.
io::MarkerTrial read_markers_file(const std::string& path, bool keep_zeros);

}  // namespace fabrik::python
