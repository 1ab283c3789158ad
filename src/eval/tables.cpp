#include "tables.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>

#include "io/output_file.hpp"
#include "solver/units.hpp"
#include "text_format.hpp"

namespace fabrik::eval {

std::string walk_table(const WalkReport& r) {
  std::string out;
  const std::size_t frames = r.rms_m.size();
  out += "frames                      " + std::to_string(frames) + " at " + fmt("%g", r.rate_hz) +
         " Hz, " + fmt("%.1f", r.iterations_mean) + " solver iterations on average\n";
  out += "marker residual RMS         " + mm2(r.rms_mean_m) + " mm mean over frames (worst frame " +
         mm2(r.rms_worst_m) + " mm)\n";
  out += "per-frame max residual      " + mm2(r.max_m_over_frames) + " mm at most (" +
         r.max_marker + ", frame " + std::to_string(r.max_frame) + ")\n";
  out += "rigid-cluster bound         " + mm2(r.cluster_max_over_frames_m) + " mm at most (" +
         r.cluster_max_marker + ", frame " + std::to_string(r.cluster_max_frame) +
         "): each segment's markers fitted alone, no joints\n\n";
  out += pad("marker", 16) + pad("segment", 12) + pad("RMS mm", 8, true) + pad("max mm", 8, true) +
         "\n";
  std::vector<MarkerStats> sorted = r.markers;
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const MarkerStats& a, const MarkerStats& b) { return a.rms_m > b.rms_m; });
  for (const MarkerStats& m : sorted)
    out += pad(m.marker, 16) + pad(m.segment, 12) + pad(mm2(m.rms_m), 8, true) +
           pad(mm2(m.max_m), 8, true) + "\n";
  return out;
}

nlohmann::json walk_json(const WalkReport& r) {
  nlohmann::json markers = nlohmann::json::array();
  for (const MarkerStats& m : r.markers)
    markers.push_back({{"marker", m.marker},
                       {"segment", m.segment},
                       {"rms_mm", m.rms_m * 1e3},
                       {"max_mm", m.max_m * 1e3},
                       {"samples", m.samples}});
  return {{"frames", r.rms_m.size()},
          {"rate_hz", r.rate_hz},
          {"rms_mean_mm", r.rms_mean_m * 1e3},
          {"rms_worst_frame_mm", r.rms_worst_m * 1e3},
          {"max_mm", r.max_m_over_frames * 1e3},
          {"max_frame", r.max_frame},
          {"max_marker", r.max_marker},
          {"cluster_bound_max_mm", r.cluster_max_over_frames_m * 1e3},
          {"cluster_bound_frame", r.cluster_max_frame},
          {"cluster_bound_marker", r.cluster_max_marker},
          {"iterations_mean", r.iterations_mean},
          {"markers", markers}};
}

void write_walk_csv(const std::string& path, const WalkReport& r) {
  std::ofstream out = io::open_output_file(path);
  out << "frame,time_s,rms_mm,max_mm,worst_marker,cluster_max_mm,cluster_worst_marker\n";
  for (std::size_t f = 0; f < r.rms_m.size(); ++f)
    out << r.clock.number(f) << ',' << fmt("%.4f", r.clock.time_s(f)) << ','
        << fmt("%.3f", r.rms_m[f] * 1e3) << ',' << fmt("%.3f", r.max_m[f] * 1e3) << ','
        << r.worst[f] << ',' << fmt("%.3f", r.cluster_max_m[f] * 1e3) << ',' << r.cluster_worst[f]
        << '\n';
  io::finish_output_file(out, path);
}

std::string gaps_table(const GapReport& r) {
  std::string out;
  std::vector<double> windows;
  std::vector<GapMode> modes;
  for (const GapSummary& s : r.summary) {
    if (std::find(windows.begin(), windows.end(), s.window_s) == windows.end())
      windows.push_back(s.window_s);
    if (std::find(modes.begin(), modes.end(), s.mode) == modes.end()) modes.push_back(s.mode);
  }
  out +=
      "Withheld marker vs its gap-filled position (RMS mm per gap length); live also the joint\n"
      "centres and end sites vs the all-markers solution (RMS mm, at the longest gap) and their\n"
      "largest step on the marker's return beyond the neighbouring frames' (mm, over all gaps)\n";
  std::vector<std::string> names;
  for (const GapStats& g : r.rows)
    if (std::find(names.begin(), names.end(), g.marker) == names.end()) names.push_back(g.marker);
  for (GapMode mode : modes) {
    out += std::string("\n") + to_string(mode) + "\n" + pad("marker", 16);
    for (double w : windows) out += pad(fmt("%gs", w), 8, true);
    if (mode == GapMode::live) out += pad("joint RMS", 10, true) + pad("return", 8, true);
    out += "\n";
    for (const std::string& name : names) {
      out += pad(name, 16);
      const GapStats* last = nullptr;
      double jump_m = 0.0;
      for (double w : windows) {
        const auto it = std::find_if(r.rows.begin(), r.rows.end(), [&](const GapStats& g) {
          return g.marker == name && g.window_s == w && g.mode == mode;
        });
        if (it == r.rows.end()) {
          out += pad("-", 8, true);
          continue;
        }
        out += pad(mm2(it->rms_m), 8, true);
        last = &*it;
        jump_m = std::max(jump_m, it->return_jump_m);
      }
      if (mode == GapMode::live)
        out += pad(last ? mm2(last->joint_rms_m) : "-", 10, true) + pad(mm2(jump_m), 8, true);
      out += "\n";
    }
  }
  out += "\n";
  for (const GapSummary& s : r.summary) {
    out += std::string(to_string(s.mode)) + (s.mode == GapMode::live ? "    " : " ") +
           fmt("%g s gaps: ", s.window_s) +
           std::to_string(s.markers) + " markers, " + std::to_string(s.windows) +
           " windows; median over markers RMS " + mm2(s.median_rms_m) + " mm, max " +
           mm2(s.median_max_m) + " mm; worst marker " + s.worst_marker + " " +
           mm2(s.worst_rms_m) + " mm RMS";
    if (s.mode == GapMode::live)
      out += "; joints " + mm2(s.joint_rms_m) + " mm RMS, " + mm2(s.joint_max_m) +
             " mm max; return jump " + mm2(s.return_jump_m) + " mm";
    out += "\n";
  }
  return out;
}

nlohmann::json gaps_json(const GapReport& r) {
  nlohmann::json rows = nlohmann::json::array(), summary = nlohmann::json::array();
  for (const GapStats& g : r.rows)
    rows.push_back({{"marker", g.marker},
                    {"mode", to_string(g.mode)},
                    {"window_s", g.window_s},
                    {"windows", g.windows},
                    {"samples", g.samples},
                    {"rms_mm", g.rms_m * 1e3},
                    {"max_mm", g.max_m * 1e3},
                    {"joint_rms_mm", g.joint_rms_m * 1e3},
                    {"joint_max_mm", g.joint_max_m * 1e3},
                    {"return_jump_mm", g.return_jump_m * 1e3}});
  for (const GapSummary& s : r.summary)
    summary.push_back({{"mode", to_string(s.mode)},
                       {"window_s", s.window_s},
                       {"markers", s.markers},
                       {"windows", s.windows},
                       {"median_rms_mm", s.median_rms_m * 1e3},
                       {"median_max_mm", s.median_max_m * 1e3},
                       {"worst_marker", s.worst_marker},
                       {"worst_rms_mm", s.worst_rms_m * 1e3},
                       {"joint_rms_mm", s.joint_rms_m * 1e3},
                       {"joint_max_mm", s.joint_max_m * 1e3},
                       {"return_jump_mm", s.return_jump_m * 1e3}});
  return {{"summary", summary}, {"markers", rows}};
}

void write_gaps_csv(const std::string& path, const GapReport& r) {
  std::ofstream out = io::open_output_file(path);
  out << "marker,mode,window_s,start_frame,frame,time_s,real_x_mm,real_y_mm,real_z_mm,pred_x_mm,"
         "pred_y_mm,pred_z_mm,error_mm\n";
  for (const GapTrace& t : r.traces)
    for (std::size_t k = 0; k < t.real_m.size(); ++k) {
      const std::size_t f = t.first_frame + k;
      out << t.marker << ',' << to_string(t.mode) << ',' << t.window_s << ','
          << r.clock.number(t.first_frame) << ',' << r.clock.number(f) << ','
          << fmt("%.4f", r.clock.time_s(f));
      for (const Eigen::Vector3d* v : {&t.real_m[k], &t.predicted_m[k]})
        for (int a = 0; a < 3; ++a) out << ',' << fmt("%.3f", (*v)[a] * 1e3);
      out << ',' << fmt("%.3f", (t.predicted_m[k] - t.real_m[k]).norm() * 1e3) << '\n';
    }
  io::finish_output_file(out, path);
}

std::string reduction_table(const std::vector<ReductionRow>& rows) {
  if (rows.empty()) return "no drop sets\n";
  std::string out =
      "Joint centres and end sites with markers left out, vs the full set (mm: RMS/max over\n"
      "frames and both sides)\n\n";
  out += pad("drop set", 28) + pad("kept", 5, true) + pad("all RMS", 8, true) +
         pad("all max", 8, true);
  for (const GroupDeviation& g : rows.front().groups) out += pad(g.group, 10, true);
  out += pad("marker RMS", 11, true) + "\n";
  for (const ReductionRow& r : rows) {
    out += pad(r.name, 28) + pad(std::to_string(r.kept), 5, true) + pad(mm2(r.rms_m), 8, true) +
           pad(mm2(r.max_m), 8, true);
    for (const GroupDeviation& g : r.groups)
      out += pad(fmt("%.1f", g.rms_m * 1e3) + "/" + fmt("%.0f", g.max_m * 1e3), 10, true);
    out += pad(mm2(r.marker_rms_mean_m), 11, true) + "\n";
  }
  return out;
}

nlohmann::json reduction_json(const std::vector<ReductionRow>& rows) {
  nlohmann::json out = nlohmann::json::array();
  for (const ReductionRow& r : rows) {
    nlohmann::json groups = nlohmann::json::object();
    for (const GroupDeviation& g : r.groups)
      groups[g.group] = {{"rms_mm", g.rms_m * 1e3}, {"max_mm", g.max_m * 1e3}};
    out.push_back({{"name", r.name},
                   {"dropped", r.dropped},
                   {"kept", r.kept},
                   {"rms_mm", r.rms_m * 1e3},
                   {"max_mm", r.max_m * 1e3},
                   {"max_point", r.max_point},
                   {"marker_rms_mean_mm", r.marker_rms_mean_m * 1e3},
                   {"groups", groups}});
  }
  return out;
}

std::string synthetic_table(const std::vector<SyntheticRow>& rows) {
  std::string out = "Joint centres vs the synthetic truth (every joint, every frame)\n\n";
  out += pad("noise mm", 9, true) + pad("frames", 7, true) + pad("RMS mm", 8, true) +
         pad("p99 mm", 8, true) + pad("max mm", 8, true) + pad("marker RMS", 11, true) + "\n";
  for (const SyntheticRow& r : rows)
    out += pad(fmt("%g", r.noise_mm), 9, true) + pad(std::to_string(r.frames), 7, true) +
           pad(mm2(r.joint_rms_m), 8, true) + pad(mm2(r.joint_p99_m), 8, true) +
           pad(mm2(r.joint_max_m), 8, true) + pad(mm2(r.marker_rms_mean_m), 11, true) + "\n";
  return out;
}

nlohmann::json synthetic_json(const std::vector<SyntheticRow>& rows) {
  nlohmann::json out = nlohmann::json::array();
  for (const SyntheticRow& r : rows)
    out.push_back({{"noise_mm", r.noise_mm},
                   {"frames", r.frames},
                   {"joint_rms_mm", r.joint_rms_m * 1e3},
                   {"joint_p99_mm", r.joint_p99_m * 1e3},
                   {"joint_max_mm", r.joint_max_m * 1e3},
                   {"marker_rms_mean_mm", r.marker_rms_mean_m * 1e3}});
  return out;
}

namespace {


// Display units: degrees for rotations, millimetres for translations.
double display(const CoordinateComparison& c, double si) {
  return si * (c.kind == CoordinateKind::rotation ? kDegPerRad : 1e3);
}
const char* display_unit(const CoordinateComparison& c) {
  return c.kind == CoordinateKind::rotation ? "deg" : "mm";
}
std::string list(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? "none" : out;
}

}  // namespace

std::string angles_table(const AngleReport& r) {
  std::string out = "Coordinates vs " + r.reference_file + ": " + std::to_string(r.time_s.size()) +
                    " frames shared";
  if (!r.time_s.empty())
    out += " (" + fmt("%.3f", r.time_s.front()) + "-" + fmt("%.3f", r.time_s.back()) + " s)";
  out += "\nmarker residual over the whole trial: " + mm2(r.residual_rms_mean_m) +
         " mm mean RMS, " + mm2(r.residual_max_m) + " mm max (" + r.residual_max_marker +
         ", frame " + std::to_string(r.residual_max_frame) + ")\n\n";
  out += pad("coordinate", 20) + pad("unit", 5) + pad("RMS", 8, true) + pad("offset", 8, true) +
         pad("RMS-off", 8, true) + pad("r", 7, true) + pad("ROM fab", 8, true) +
         pad("ROM ref", 8, true) + "\n";
  for (const CoordinateComparison& c : r.rows) {
    const std::string pr = std::isnan(c.pearson_r) ? "-" : fmt("%.3f", c.pearson_r);
    out += pad(c.name, 20) + pad(display_unit(c), 5) + pad(fmt("%.2f", display(c, c.rms_si)), 8, true) +
           pad(fmt("%.2f", display(c, c.offset_si)), 8, true) +
           pad(fmt("%.2f", display(c, c.rms_centered_si)), 8, true) + pad(pr, 7, true) +
           pad(fmt("%.1f", display(c, c.range_fabrik_si)), 8, true) +
           pad(fmt("%.1f", display(c, c.range_reference_si)), 8, true) + "\n";
  }
  out += "\nRMS-off: RMS after removing the mean offset (fabrik - reference); r: Pearson;\n"
         "ROM: range of motion (max - min) over the shared frames\n";
  out += "in the model, not in the reference: " + list(r.not_in_reference) + "\n";
  out += "in the reference, not in the model: " + list(r.not_in_model) + "\n";
  return out;
}

nlohmann::json angles_json(const AngleReport& r) {
  nlohmann::json rows = nlohmann::json::array();
  for (const CoordinateComparison& c : r.rows) {
    nlohmann::json row = {{"name", c.name},
                          {"unit", display_unit(c)},
                          {"samples", c.samples},
                          {"rms", display(c, c.rms_si)},
                          {"offset", display(c, c.offset_si)},
                          {"rms_offset_removed", display(c, c.rms_centered_si)},
                          {"pearson_r", nullptr},
                          {"range_fabrik", display(c, c.range_fabrik_si)},
                          {"range_reference", display(c, c.range_reference_si)}};
    if (!std::isnan(c.pearson_r)) row["pearson_r"] = c.pearson_r;
    rows.push_back(row);
  }
  return {{"reference", r.reference_file},
          {"frames_shared", r.time_s.size()},
          {"time_first_s", r.time_s.empty() ? 0.0 : r.time_s.front()},
          {"time_last_s", r.time_s.empty() ? 0.0 : r.time_s.back()},
          {"residual_mm",
           {{"rms_mean", r.residual_rms_mean_m * 1e3},
            {"max", r.residual_max_m * 1e3},
            {"max_frame", r.residual_max_frame},
            {"max_marker", r.residual_max_marker}}},
          {"coordinates", rows},
          {"not_in_reference", r.not_in_reference},
          {"not_in_model", r.not_in_model}};
}

void write_angles_csv(const std::string& path, const AngleReport& r) {
  std::ofstream out = io::open_output_file(path);
  out << "coordinate,unit,frame,time_s,fabrik,reference\n";
  for (const CoordinateComparison& c : r.rows)
    for (std::size_t k = 0; k < c.fabrik_si.size(); ++k)
      out << c.name << ',' << display_unit(c) << ',' << r.frame_numbers[k] << ','
          << fmt("%.5f", r.time_s[k]) << ',' << fmt("%.4f", display(c, c.fabrik_si[k])) << ','
          << fmt("%.4f", display(c, c.reference_si[k])) << '\n';
  io::finish_output_file(out, path);
}

}  // namespace fabrik::eval
