// The evaluations' results as text tables (for the terminal and docs/),
// JSON (--json) and CSV (for scripts/plot_*.py). Lengths in mm, angles in degrees.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "angles.hpp"
#include "gaps.hpp"
#include "reduction.hpp"
#include "synthetic.hpp"
#include "walk.hpp"

namespace fabrik::eval {

std::string walk_table(const WalkReport& r);
nlohmann::json walk_json(const WalkReport& r);
// frame,time_s,rms_mm,max_mm,worst_marker,cluster_max_mm,cluster_worst_marker
void write_walk_csv(const std::string& path, const WalkReport& r);

std::string gaps_table(const GapReport& r);
nlohmann::json gaps_json(const GapReport& r);
// marker,window_s,start_frame,frame,time_s,real_{x,y,z}_mm,pred_{x,y,z}_mm,error_mm
void write_gaps_csv(const std::string& path, const GapReport& r);

std::string reduction_table(const std::vector<ReductionRow>& rows);
nlohmann::json reduction_json(const std::vector<ReductionRow>& rows);

std::string synthetic_table(const std::vector<SyntheticRow>& rows);
nlohmann::json synthetic_json(const std::vector<SyntheticRow>& rows);

// Rotations in degrees, translations in millimetres; "-" where r is undefined.
std::string angles_table(const AngleReport& r);
nlohmann::json angles_json(const AngleReport& r);
// coordinate,unit,frame,time_s,fabrik,reference (deg or mm), for scripts/plot_angles.py
void write_angles_csv(const std::string& path, const AngleReport& r);

}  // namespace fabrik::eval
