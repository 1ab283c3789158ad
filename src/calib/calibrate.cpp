#include "calibrate.hpp"
#include "derive_anatomy.hpp"
#include "static_window.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>

#include "config/closest_names.hpp"
#include "config/config_error.hpp"
#include "config/daemon_config.hpp"
#include "config/model_loader.hpp"
#include "config/solver_options_json.hpp"
#include "tracking/tracker.hpp"

namespace fabrik::calib {

const Eigen::Vector3d& CalibrationResult::point_world_m(const std::string& name) const {
  for (const auto& [n, p] : points_world_m)
    if (n == name) return p;
  throw std::out_of_range("no calibrated point '" + name + "'");
}

namespace {

// Unsigned angle between two directions, robust near 0 and 180 deg.
double angle_between_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / std::numbers::pi;
}

// The subtree carry of a calibrated model with joint limits (docs/joint-limits.md, "Subtree
// carry": the share that closed most of the gap to the constrained least-squares fit).
constexpr double kCalibratedSubtreeCarry = 0.5;

// Model files are written in millimetres with 1 um resolution: far below
// marker noise, and it keeps the file readable.
double mm(double metres) {
  return std::round(metres * 1e6) / 1e3;
}
nlohmann::ordered_json mm3(const Eigen::Vector3d& v) {
  return {mm(v.x()), mm(v.y()), mm(v.z())};
}
// A unit axis, to 1e-9 (well within the model loader's orthogonality check).
nlohmann::ordered_json unit3(const Eigen::Vector3d& v) {
  auto r = [](double x) { return std::round(x * 1e9) / 1e9; };
  return {r(v.x()), r(v.y()), r(v.z())};
}

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

class Calibrator {
 public:
  Calibrator(const CalibTemplate& t, const io::MarkerTrial& trial, std::string trial_name,
             const BuiltRest* built = nullptr)
      : t_(t), trial_(trial), trial_name_(std::move(trial_name)), built_(built) {}

  CalibrationResult run(const CalibrateOptions& o) {
    match_labels();
    choose_window(o);
    if (built_) {
      r_.built_rest = true;
    } else {
      report_motion();
    }
    average();
    resolved_.assign(t_.points.size(), std::nullopt);
    for (std::size_t i = 0; i < t_.points.size(); ++i)
      r_.points_world_m.emplace_back(t_.points[i].name, point(static_cast<int>(i)));
    derive();
    choose_lab_axes(o);
    build_model();
    fit();
    return std::move(r_);
  }

 private:
  [[noreturn]] void fail(const std::string& problem, const std::string& fix) const {
    throw CalibrationError(trial_name_ + ": " + problem + (fix.empty() ? "" : ". Fix: " + fix));
  }

  void choose_window(const CalibrateOptions& o) {
    const long long n = static_cast<long long>(trial_.frames());
    if (n == 0) fail("the trial has no frames", "record a static trial");
    const long long first_no = trial_.first_frame;
    if (o.auto_window > 0) {
      if (o.first_frame >= 0 || o.frames >= 0)
        fail("--auto-window picks the window itself", "give --auto-window N, or --first-frame "
             "and --frames, not both");
      if (o.auto_window > n)
        fail("--auto-window " + std::to_string(o.auto_window) + " is longer than the trial (" +
                 std::to_string(n) + " frames)",
             "use at most " + std::to_string(n) + " frames");
      first_ = stillest_window(trial_, column_, static_cast<std::size_t>(o.auto_window));
      count_ = static_cast<std::size_t>(o.auto_window);
      r_.first_frame = first_no + static_cast<long long>(first_);
      r_.frames = o.auto_window;
      return;
    }
    const FrameWindow w = frame_window(trial_, trial_name_, o.first_frame, o.frames);
    first_ = w.first;
    count_ = w.count;
    const long long start = w.first_frame_number, count = static_cast<long long>(w.count);
    r_.first_frame = start;
    r_.frames = count;
  }

  void report_motion() {
    const WindowMotion w = window_motion(trial_, column_, first_, count_);
    r_.window_motion_m = w.motion_m;
    if (w.column >= 0) r_.window_motion_marker = trial_.labels[static_cast<std::size_t>(w.column)];
    if (w.motion_m > kStillWindowWarn_m)
      r_.notes.push_back("the subject moved in the static window: marker '" +
                         r_.window_motion_marker + "' is up to " + fmt("%.1f", w.motion_m * 1e3) +
                         " mm from its mean there (more than " +
                         fmt("%.0f", kStillWindowWarn_m * 1e3) +
                         " mm); the model averages a posture nobody held. Fix: choose a still "
                         "window (--first-frame/--frames), or --auto-window N for the stillest N "
                         "frames");
  }

  // A template name matches a label exactly, or a "Subject:name" label as
  // Vicon writes them.
  void match_labels() {
    column_.assign(t_.markers.size(), -1);
    std::set<int> used;
    for (std::size_t m = 0; m < t_.markers.size(); ++m) {
      const std::string& name = t_.markers[m].name;
      int col = trial_.find(name);
      if (col < 0) {
        for (std::size_t l = 0; l < trial_.labels.size(); ++l) {
          const std::string& lab = trial_.labels[l];
          if (lab.size() > name.size() &&
              lab.compare(lab.size() - name.size(), name.size(), name) == 0 &&
              lab[lab.size() - name.size() - 1] == ':') {
            if (col >= 0)
              fail("template marker '" + name + "' matches both '" + trial_.labels[col] +
                       "' and '" + lab + "'",
                   "rename the markers so each label matches one template marker");
            col = static_cast<int>(l);
          }
        }
        if (col >= 0) ++prefixed_;
      }
      column_[m] = col;
      if (col >= 0) used.insert(col);
    }
    if (prefixed_ > 0)
      r_.notes.push_back(std::to_string(prefixed_) +
                         " template markers matched trial labels with a subject prefix "
                         "('Subject:NAME'); the model uses the template names, the config maps the "
                         "labels onto them");
    std::string ignored;
    int n_ignored = 0;
    for (std::size_t l = 0; l < trial_.labels.size(); ++l)
      if (!used.count(static_cast<int>(l))) {
        ignored += (n_ignored++ ? ", " : "") + trial_.labels[l];
      }
    if (n_ignored)
      r_.notes.push_back(std::to_string(n_ignored) +
                         " trial markers are not in the template and were ignored: " + ignored);
  }

  // The markers the model needs: every tracked marker, and every marker a
  // point or frame is defined from.
  std::set<std::string> needed_markers() const {
    std::set<std::string> names;
    for (const MarkerDef& m : t_.markers)
      if (!m.static_only) names.insert(m.name);
    auto add = [&](const PointRef& r) {
      for (const std::string& n : r.names)
        if (t_.find_marker(n) >= 0) names.insert(n);
    };
    for (const PointDef& p : t_.points) {
      for (const PointRef& r : p.refs) add(r);
      if (p.rule == PointRule::regression) {
        add(p.r_asis);
        add(p.l_asis);
        add(p.posterior);
      }
      if (p.frame >= 0) {
        const FrameSpec& f = t_.frames[p.frame];
        for (const PointRef* r :
             {&f.primary.from, &f.primary.to, &f.secondary.from, &f.secondary.to})
          add(*r);
      }
    }
    return names;
  }

  // Mean of each marker's valid samples in the window; missing samples are skipped.
  void average() {
    mean_.assign(t_.markers.size(), Eigen::Vector3d::Constant(NAN));
    const std::set<std::string> needed = needed_markers();
    std::string absent;
    int n_absent = 0;
    std::vector<std::string> not_in_trial;
    for (std::size_t m = 0; m < t_.markers.size(); ++m) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      std::size_t n = 0;
      if (column_[m] >= 0)
        for (std::size_t f = first_; f < first_ + count_; ++f) {
          const Eigen::Vector3d& p = trial_.at(f, static_cast<std::size_t>(column_[m]));
          if (p.allFinite()) {
            sum += p;
            ++n;
          }
        }
      if (n > 0) mean_[m] = sum / static_cast<double>(n);
      const std::string& name = t_.markers[m].name;
      if (!needed.count(name)) continue;
      if (n == 0) {
        absent += std::string(n_absent++ ? ", " : "") + "'" + name + "'" +
                  (column_[m] < 0 ? " (not in the trial)" : " (no sample in the window)");
        if (column_[m] < 0) not_in_trial.push_back(name);
      } else if (n < count_) {
        r_.notes.push_back("marker '" + name + "' is missing in " + std::to_string(count_ - n) +
                           " of the " + std::to_string(count_) +
                           " frames; it is averaged over the others");
      }
    }
    // A lab's own spelling of the set (R_ASIS for R.ASIS) is most often the reason: the
    // closest labels say so, as fabrik solve's refusal does.
    std::string closest;
    constexpr std::size_t kClosestShown = 6;
    const std::vector<NameMatch> matches = closest_labels(not_in_trial, trial_.labels);
    for (std::size_t k = 0; k < std::min(matches.size(), kClosestShown); ++k)
      closest += std::string(k ? ", " : "; closest labels: ") + matches[k].config_name + " ~ " +
                 matches[k].trial_label + " (" + matches[k].how + ")";
    if (matches.size() > kClosestShown)
      closest += ", ... (" + std::to_string(matches.size()) + " in all)";
    if (n_absent)
      fail(std::to_string(n_absent) + " marker(s) the template needs have no position in frames " +
               std::to_string(r_.first_frame) + " to " +
               std::to_string(r_.first_frame + r_.frames - 1) + ": " + absent + closest,
           "use a static trial that has these markers (or choose a window with --first-frame "
           "and --frames where they are visible), or change the template " +
               t_.file);
  }

  Eigen::Vector3d name_position(const std::string& name) {
    if (const int p = t_.find_point(name); p >= 0) return point(p);
    const int m = t_.find_marker(name);  // the loader checked every name exists
    return mean_[m];
  }

  Eigen::Vector3d ref_position(const PointRef& ref) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const std::string& n : ref.names) sum += name_position(n);
    return sum / static_cast<double>(ref.names.size());
  }

  Eigen::Vector3d unit(const Eigen::Vector3d& v, const std::string& what,
                       const std::string& pointer) const {
    if (v.norm() < 1e-4)
      fail(what + " (" + t_.file + " at " + pointer + ") has no direction: its markers coincide",
           "define it from markers at least a few centimetres apart");
    return v.normalized();
  }

  // Columns: the frame's x, y and z axes in the world.
  Eigen::Matrix3d frame(const FrameSpec& f) {
    const Eigen::Vector3d a =
        unit(ref_position(f.primary.to) - ref_position(f.primary.from), "a frame axis", f.pointer);
    Eigen::Vector3d b = ref_position(f.secondary.to) - ref_position(f.secondary.from);
    b -= a * a.dot(b);
    b = unit(b, "the frame's second axis, made orthogonal to the first,", f.pointer);
    Eigen::Matrix3d r;
    r.col(f.primary.axis) = a;
    r.col(f.secondary.axis) = b;
    const int i = f.primary.axis, j = f.secondary.axis, k = 3 - i - j;
    // Right-handed: z = x cross y and its cyclic permutations.
    r.col(k) = ((j - i + 3) % 3 == 1) ? a.cross(b) : b.cross(a);
    return r;
  }

  Eigen::Vector3d regression(const PointDef& d) {
    const Eigen::Vector3d ra = ref_position(d.r_asis), la = ref_position(d.l_asis);
    const Eigen::Vector3d post = ref_position(d.posterior);
    const Eigen::Vector3d origin = 0.5 * (ra + la);
    // Pelvis frame: z to the right through the ASIS, x anterior in the plane
    // of the ASIS and the posterior reference, y superior.
    const Eigen::Vector3d z = unit(ra - la, "the pelvis left-right axis", d.pointer);
    Eigen::Vector3d x = origin - post;
    x = unit(x - z * z.dot(x), "the pelvis anterior axis", d.pointer);
    Eigen::Matrix3d r;
    r << x, z.cross(x), z;
    const double pw = (ra - la).norm(), pd = (origin - post).norm();
    return origin + r * hip_centre_in_pelvis_m(d.regression, d.right, pw, pd);
  }

  Eigen::Vector3d point(int i) {
    if (resolved_[i]) return *resolved_[i];
    const PointDef& d = t_.points[i];
    Eigen::Vector3d p;
    switch (d.rule) {
      case PointRule::at:
        p = ref_position(d.refs[0]);
        break;
      case PointRule::midpoint:
        p.setZero();
        for (const PointRef& r : d.refs) p += ref_position(r);
        p /= static_cast<double>(d.refs.size());
        break;
      case PointRule::offset:
        p = ref_position(d.refs[0]) + frame(t_.frames[d.frame]) * d.offset_m;
        break;
      case PointRule::regression:
        p = regression(d);
        break;
    }
    resolved_[i] = p;
    return p;
  }

  // Frames and coordinates the template leaves out (derive_anatomy.hpp).
  void derive() {
    std::vector<Eigen::Vector3d> points;
    for (const auto& [name, p] : r_.points_world_m) points.push_back(p);
    std::vector<std::optional<Eigen::Matrix3d>> given(t_.segments.size());
    for (std::size_t s = 0; s < t_.segments.size(); ++s)
      if (built_) given[s] = built_->axes_lab;
      else if (t_.segments[s].frame >= 0) given[s] = frame(t_.frames[t_.segments[s].frame]);
    derived_ = derive_anatomy(t_, points, mean_, given);
    r_.derived = derived_.report;
  }

  // The static pose's superior direction: the sum of the segments' anatomical
  // y axes (superior or proximal, as ISB's frames); and its anterior one: the
  // root's x axis (the pelvis's front), else the sum of the x axes. Zero
  // without segment frames (the template's, else derived ones).
  std::optional<Eigen::Matrix3d> segment_axes(std::size_t s) {
    if (built_) return built_->axes_lab;
    if (t_.segments[s].frame >= 0) return frame(t_.frames[t_.segments[s].frame]);
    if (s < derived_.frames.size()) return derived_.frames[s];
    return std::nullopt;
  }
  std::pair<Eigen::Vector3d, Eigen::Vector3d> static_directions() {
    Eigen::Vector3d superior = Eigen::Vector3d::Zero(), anterior = Eigen::Vector3d::Zero();
    for (std::size_t s = 0; s < t_.segments.size(); ++s) {
      const std::optional<Eigen::Matrix3d> axes = segment_axes(s);
      if (!axes) continue;
      superior += axes->col(1);
      anterior += axes->col(0);
    }
    if (const std::optional<Eigen::Matrix3d> root = segment_axes(0)) anterior = root->col(0);
    return {superior, anterior};
  }

  // Declared (command line, else template) or detected: up is the signed lab
  // axis nearest the static pose's superior direction; forward stays +x while
  // x is horizontal, else it is the horizontal lab axis nearest the anterior
  // direction. Without segment frames nothing can be detected: Y up is kept.
  void choose_lab_axes(const CalibrateOptions& o) {
    const std::optional<LabAxesSpec>& declared = o.lab_axes ? o.lab_axes : t_.lab_axes;
    const std::string where = o.lab_axes ? "with --lab-up/--lab-forward" : "in the template";
    const auto [superior, anterior] = static_directions();
    const bool has_frames = superior.norm() > 1e-9;
    const auto nearest_axis = nearest_lab_axis;
    Eigen::Vector3d up = Eigen::Vector3d::UnitY();
    std::string how;
    if (declared) {
      up = declared->up_lab;
      how = "declared " + where;
      if (auto note = declared_up_note(up, superior,
                                       "the static pose's superior direction (the segments' "
                                       "anatomical y axes)"))
        r_.notes.push_back(std::move(*note));
    } else if (has_frames) {
      up = nearest_axis(superior, Eigen::Vector3d::Zero());
      how =
          "detected from the static trial: up is the lab axis nearest the segments' superior "
          "(anatomical y) axes, " +
          fmt("%.1f", angle_between_deg(superior, up)) + " deg from their mean";
    } else {
      how = "assumed: the template gives no segment frames to detect them from";
    }
    std::optional<Eigen::Vector3d> forward = declared ? declared->forward_lab : std::nullopt;
    const Eigen::Vector3d front = anterior - up * up.dot(anterior);  // horizontal
    if (!forward) {
      forward = default_forward_lab(up);
      if (forward) {
        how += "; forward is +x, which is horizontal (kept, so a lab with X forward keeps its "
               "numbers)";
      } else if (front.norm() > 1e-9) {
        forward = nearest_axis(front, up);
        how += "; forward is the horizontal lab axis nearest the " +
               std::string(segment_axes(0) ? "root segment's" : "segments'") +
               " anterior (anatomical x) axis";
      } else {
        forward = nearest_axis(Eigen::Vector3d(0, 1, 1), up);
        how += "; forward is " + signed_axis_name(*forward) + " (no anterior direction to go by)";
      }
    }
    // OpenSim's pelvis angles assume the subject faces about forward: facing
    // sideways, pelvis_rotation sits near 90 deg and tilt and list swap roles;
    // facing backwards, near 180 deg with tilt and list of the other sign.
    if (const double off = front.norm() > 1e-9 ? angle_between_deg(front, *forward) : 0.0;
        off > 45.0)
      r_.notes.push_back("the subject faces " + signed_axis_name(nearest_axis(front, up)) +
                         " in the static trial, " + fmt("%.0f", off) +
                         " deg from the lab's forward axis " + signed_axis_name(*forward) +
                         ": pelvis_rotation will sit near that angle and pelvis_tilt and "
                         "pelvis_list " + (off > 135.0 ? "change sign" : "swap roles") +
                         ". Fix: if the subject walks along " +
                         signed_axis_name(nearest_axis(front, up)) + ", declare it forward "
                         "(--lab-forward or \"lab_axes\" in the template)");
    r_.lab_axes = LabAxes{up, *forward};
    r_.lab_axes_how = how;
  }

  void build_model() {
    nlohmann::ordered_json segs = nlohmann::ordered_json::array();
    for (std::size_t s = 0; s < t_.segments.size(); ++s) {
      const SegmentDef& sd = t_.segments[s];
      const Eigen::Vector3d base = point(t_.find_point(sd.base));
      nlohmann::ordered_json seg;
      seg["name"] = sd.name;
      if (sd.parent >= 0) seg["parent"] = t_.segments[sd.parent].name;
      seg["base"] = sd.base;
      nlohmann::ordered_json pts = nlohmann::ordered_json::object();
      for (std::size_t p = 0; p < t_.points.size(); ++p) {
        const PointDef& pd = t_.points[p];
        if (pd.segment != static_cast<int>(s) || pd.name == sd.base) continue;
        const Eigen::Vector3d w = point(static_cast<int>(p));
        pts[pd.name] = mm3(w - base);
        r_.lengths.push_back({sd.name, sd.base, pd.name, (w - base).norm()});
      }
      nlohmann::ordered_json mks = nlohmann::ordered_json::object();
      for (std::size_t m = 0; m < t_.markers.size(); ++m) {
        const MarkerDef& md = t_.markers[m];
        if (md.segment != static_cast<int>(s) || md.static_only) continue;
        mks[md.name] = mm3(mean_[m] - base);
      }
      if (!pts.empty()) seg["points"] = pts;
      if (!mks.empty()) seg["markers"] = mks;
      if (const std::optional<Eigen::Matrix3d> axes_at_rest = segment_axes(s)) {
        // The anatomical frame at the static pose, which is the rest pose.
        const Eigen::Matrix3d axes = *axes_at_rest;
        seg["frame"] = {{"x", unit3(axes.col(0))}, {"y", unit3(axes.col(1))},
                        {"z", unit3(axes.col(2))}};
      }
      if (!sd.joint.is_null()) seg["joint"] = nlohmann::ordered_json::parse(sd.joint.dump());
      segs.push_back(seg);
    }
    const SegmentDef& root = t_.segments[0];
    r_.model["format"] = "fabrikd-model/1";
    r_.model["name"] = t_.name;
    r_.model["description"] =
        built_ ? "Calibrated by fabrik calibrate from keypoint template " + t_.file + ": " +
                     built_->source
               : "Calibrated by fabrik calibrate from template " + t_.file + " and static trial " +
                     trial_name_ + " (frames " + std::to_string(r_.first_frame) + " to " +
                     std::to_string(r_.first_frame + r_.frames - 1) +
                     "): the rest posture is the averaged static posture.";
    r_.model["units"] = "mm";
    r_.model["root_position"] = mm3(point(t_.find_point(root.base)));
    r_.model["segments"] = segs;
    r_.model["lab_axes"] = lab_axes_json(r_.lab_axes);
    if (!t_.coordinates.is_null())
      r_.model["coordinates"] = nlohmann::ordered_json::parse(t_.coordinates.dump());
    else if (!derived_.coordinates.is_null())
      r_.model["coordinates"] = derived_.coordinates;

    // The targets: the template's default level and weight, and every marker that differs.
    nlohmann::ordered_json markers = nlohmann::ordered_json::object();
    for (const MarkerDef& m : t_.markers) {
      if (m.static_only) continue;
      nlohmann::ordered_json e = nlohmann::ordered_json::object();
      if (m.level != t_.default_level) e["level"] = m.level;
      if (m.weight != t_.default_weight) e["weight"] = m.weight;
      // A "Subject:NAME" label streams under that name: map it onto the point.
      const std::size_t mi = static_cast<std::size_t>(&m - t_.markers.data());
      const std::string stream =
          column_[mi] >= 0 ? trial_.labels[static_cast<std::size_t>(column_[mi])] : m.name;
      if (stream != m.name) e["point"] = m.name;
      if (!e.empty()) markers[stream] = e;
    }
    // The rest mirrors config/default.json, so a calibrated config behaves like the default.
    auto& c = r_.config;
    c["format"] = "fabrikd-config/1";
    c["description"] = "Subject model '" + t_.name + "' calibrated from " + trial_name_ +
                       " with template " + t_.file + ".";
    c["model"] = r_.model;
    c["targets"] = {{"default", {{"level", t_.default_level}, {"weight", t_.default_weight}}},
                    {"markers", markers}};
    // Every value below is the daemon's default (DaemonConfig, tracking_settings.hpp), written
    // out so that a user sees what to edit.
    const DaemonConfig d;
    SolverOptions solver = d.tracker.solver;
    // Real subjects' markers are never exactly reachable by the model: there
    // FABRIK's own fixed point with limited joints is far from the best
    // fit, and the carry closes most of the gap (docs/joint-limits.md, "Subtree carry").
    bool limited = false;
    for (const auto& sd : t_.segments) limited = limited || !sd.joint.is_null();
    if (limited) solver.subtree_carry = kCalibratedSubtreeCarry;
    c["solver"] = solver_options_json(solver);
    const auto mode = [](const Endpoint& e) { return e.mode == SocketMode::bind ? "bind" : "connect"; };
    c["input"] = {{"endpoint", d.input.address},
                  {"mode", mode(d.input)},
                  {"units", "mm"},
                  {"max_payload_bytes", d.max_payload_bytes},
                  {"max_backlog_frames", d.max_backlog_frames}};
    c["output"] = {{"endpoint", d.output.address},
                   {"mode", mode(d.output)},
                   {"encoding", d.output_encoding == Encoding::json ? "json" : "msgpack"},
                   {"units", d.output_units}};
    c["occlusion"] = {{"hold_s", d.tracker.occlusion.hold_s}};
    c["stats_interval_s"] = d.stats_interval_s;
    c["log_level"] = d.log_level;
  }

  // The written model, loaded as fabrikd will load it. Joints and coordinates
  // are the template's, copied at the same JSON pointers (segments keep the
  // template's order), so a mistake in them is reported in the template.
  Model load_calibrated_model() const {
    const std::string name = "<calibrated model>";
    try {
      return load_model(nlohmann::json::parse(r_.model.dump()), name);
    } catch (const ConfigError& e) {
      const std::string& p = e.pointer();
      const bool copied = (p.rfind("/coordinates", 0) == 0 && !t_.coordinates.is_null()) ||
                          (p.rfind("/segments/", 0) == 0 && p.find("/joint") != std::string::npos);
      const std::string prefix = name + ": at " + p + ": ";
      const std::string what = e.what();
      if (!copied || what.rfind(prefix, 0) != 0) throw;
      throw ConfigError(t_.file, p, what.substr(prefix.size()), "");
    }
  }

  // Tracks the window with the written config as `fabrik solve` would (the
  // same Tracker and settings), and measures each marker's residual and the
  // window's in solve's terms.
  void fit() {
    load_calibrated_model();  // a mistake copied from the template is reported there
    const DaemonConfig config = load_daemon_config(r_.config.dump(), "<calibrated config>");
    Tracker tracker(config.tracker);
    const Model& model = tracker.model();
    const std::vector<MarkerTarget>& targets = config.tracker.markers;
    const std::size_t n = targets.size();
    std::vector<int> tmarker(n), column(n);  // template marker and trial column of each target
    for (std::size_t i = 0; i < n; ++i) {
      tmarker[i] = t_.find_marker(model.points[targets[i].point].name);
      column[i] = column_[tmarker[i]];
    }
    const Posture rest = Posture::rest(model);
    for (std::size_t i = 0; i < n; ++i)
      r_.rest_max_m = std::max(
          r_.rest_max_m, (rest.point_world_m(model, targets[i].point) - mean_[tmarker[i]]).norm());

    std::vector<Eigen::Vector3d> pos(n);
    std::vector<std::uint8_t> vis(n);
    std::vector<double> sum2(n, 0.0), worst(n, 0.0);
    std::vector<int> count(n, 0);
    double rms_sum = 0.0;
    int frames_with_residual = 0;
    // A built rest posture is fitted to the movement it was measured from.
    const io::MarkerTrial& fit_trial = built_ ? *built_->fit_trial : trial_;
    const std::size_t fit_first = built_ ? built_->fit_first : first_;
    const std::size_t fit_count = built_ ? built_->fit_count : count_;
    for (std::size_t f = fit_first; f < fit_first + fit_count; ++f) {
      for (std::size_t i = 0; i < n; ++i) {
        pos[i] = column[i] >= 0 ? fit_trial.at(f, static_cast<std::size_t>(column[i]))
                                : Eigen::Vector3d::Constant(NAN);
        vis[i] = pos[i].allFinite();
      }
      const TrackResult& tr = tracker.track(fit_trial.time_s(f), pos, vis);
      r_.fit_outlier_samples += tr.outlier_count;
      for (std::size_t i = 0; i < n; ++i) {
        if (tr.occluded[i] || tr.outliers[i]) continue;
        const double d = tr.marker_residual_m[i];
        sum2[i] += d * d;
        worst[i] = std::max(worst[i], d);
        ++count[i];
      }
      if (tr.residual_count == 0) continue;
      ++frames_with_residual;
      rms_sum += tr.residual_rms_m;
      r_.fit_rms_worst_frame_m = std::max(r_.fit_rms_worst_frame_m, tr.residual_rms_m);
      if (tr.residual_max_m > r_.fit_max_m || r_.fit_max_marker.empty()) {
        r_.fit_max_m = tr.residual_max_m;
        r_.fit_max_marker = t_.markers[tmarker[tr.worst_marker]].name;
        r_.fit_max_frame = fit_trial.first_frame + static_cast<long long>(f);
      }
    }
    r_.fit_rms_mean_m = frames_with_residual ? rms_sum / frames_with_residual : 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const MarkerDef& md = t_.markers[tmarker[i]];
      r_.fits.push_back({md.name, t_.segments[md.segment].name,
                         count[i] ? std::sqrt(sum2[i] / count[i]) : 0.0, worst[i], count[i]});
    }
  }

  const CalibTemplate& t_;
  const io::MarkerTrial& trial_;
  std::string trial_name_;
  const BuiltRest* built_ = nullptr;
  std::size_t first_ = 0, count_ = 0;
  int prefixed_ = 0;
  std::vector<int> column_;            // per template marker: trial column, -1 if absent
  std::vector<Eigen::Vector3d> mean_;  // per template marker: static mean (NaN if none)
  std::vector<std::optional<Eigen::Vector3d>> resolved_;  // per template point
  DerivedAnatomy derived_;
  CalibrationResult r_;
};

}  // namespace

CalibrationResult calibrate(const CalibTemplate& tmpl, const io::MarkerTrial& trial,
                            const std::string& trial_name, const CalibrateOptions& options) {
  return Calibrator(tmpl, trial, trial_name).run(options);
}

Eigen::Vector3d nearest_lab_axis(const Eigen::Vector3d& v, const Eigen::Vector3d& except) {
  Eigen::Vector3d best = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) {
    if (std::abs(except[k]) > 0.5) continue;
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(k) * (v[k] < 0.0 ? -1.0 : 1.0);
    if (best.isZero() || v.dot(e) > v.dot(best)) best = e;
  }
  return best;
}

std::optional<std::string> declared_up_note(const Eigen::Vector3d& up_lab,
                                            const Eigen::Vector3d& superior_lab,
                                            const std::string& measured) {
  if (superior_lab.norm() < 1e-9) return std::nullopt;
  const double deg = angle_between_deg(superior_lab, up_lab);
  if (!(deg > 45.0)) return std::nullopt;
  return "the declared lab up axis " + signed_axis_name(up_lab) + " is " + fmt("%.0f", deg) +
         " deg from " + measured + ", which is nearest " +
         signed_axis_name(nearest_lab_axis(superior_lab, Eigen::Vector3d::Zero())) +
         ". Fix: check the lab axes you declared";
}

FrameWindow frame_window(const io::MarkerTrial& trial, const std::string& trial_name,
                         long long first_frame, long long frames) {
  const auto fail = [&](const std::string& problem, const std::string& fix) {
    throw CalibrationError(trial_name + ": " + problem + ". Fix: " + fix);
  };
  const long long n = static_cast<long long>(trial.frames());
  const long long first_no = trial.first_frame, last_no = first_no + n - 1;
  const long long start = first_frame < 0 ? first_no : first_frame;
  if (start < first_no || start > last_no)
    fail("--first-frame " + std::to_string(start) + " is outside the trial (frames " +
             std::to_string(first_no) + " to " + std::to_string(last_no) + ")",
         "choose a frame number in that range");
  const long long count = frames < 0 ? last_no - start + 1 : frames;
  if (count < 1 || start + count - 1 > last_no)
    fail("--frames " + std::to_string(count) + " from frame " + std::to_string(start) +
             " runs past the last frame " + std::to_string(last_no),
         "use at most " + std::to_string(last_no - start + 1) + " frames");
  return {static_cast<std::size_t>(start - first_no), static_cast<std::size_t>(count), start};
}

CalibrationResult calibrate_built_rest(const CalibTemplate& tmpl, const io::MarkerTrial& rest,
                                       const std::string& trial_name,
                                       const CalibrateOptions& options, const BuiltRest& built) {
  if (!built.fit_trial) throw CalibrationError(trial_name + ": no trial to fit the built rest to");
  return Calibrator(tmpl, rest, trial_name, &built).run(options);
}

std::string calibration_report(const CalibrationResult& r) {
  std::ostringstream out;
  if (!r.built_rest)
    out << "Static window: frames " << r.first_frame << " to " << r.first_frame + r.frames - 1 << " ("
      << r.frames << " frames); motion in it "
      << fmt("%.2f", r.window_motion_m * 1e3) << " mm at most ("
      << (r.window_motion_marker.empty() ? "-" : r.window_motion_marker) << ")\n";
  for (const std::string& n : r.notes) out << "note: " << n << "\n";
  if (!r.derived.empty()) out << "\n";
  for (const std::string& d : r.derived) out << d << "\n";
  out << "\nSegment lengths (base -> joint or end site):\n";
  for (const SegmentLength& l : r.lengths) {
    char line[200];
    std::snprintf(line, sizeof line, "  %-14s %-16s -> %-16s %7.1f mm\n", l.segment.c_str(),
                  l.from.c_str(), l.to.c_str(), l.length_m * 1e3);
    out << line;
  }
  out << "\nLab axes: up " << signed_axis_name(r.lab_axes.up_lab) << ", forward "
      << signed_axis_name(r.lab_axes.forward_lab) << "\n  (" << r.lab_axes_how << ")\n"
      << "  Coordinates relative to the lab (pelvis_tilt, pelvis_tx, ...) are taken in OpenSim's "
         "ground frame,\n  X forward and Y up; the config records the axes in its model's "
         "\"lab_axes\". To declare them:\n  --lab-up/--lab-forward, or \"lab_axes\": {\"up\": "
         "\"+z\", \"forward\": \"+x\"} in the template\n";
  out << "\nMarker fit: the " << (r.built_rest ? "movement (the lengths' window)" : "window")
      << " tracked with the written config, as fabrik solve tracks it (per marker: RMS and max "
         "over its frames)\n";
  out << "  marker               segment          RMS mm   max mm\n";
  for (const MarkerFit& f : r.fits) {
    char line[200];
    std::snprintf(line, sizeof line, "  %-20s %-14s %8.2f %8.2f\n", f.marker.c_str(),
                  f.segment.c_str(), f.rms_m * 1e3, f.max_m * 1e3);
    out << line;
  }
  out << "  all markers: RMS " << fmt("%.2f", r.fit_rms_mean_m * 1e3)
      << " mm (mean over frames of each frame's RMS, as fabrik solve; worst frame "
      << fmt("%.2f", r.fit_rms_worst_frame_m * 1e3) << " mm), max "
      << fmt("%.2f", r.fit_max_m * 1e3) << " mm ("
      << (r.fit_max_marker.empty() ? "-" : r.fit_max_marker) << ", frame " << r.fit_max_frame
      << ")\n";
  if (r.fit_outlier_samples > 0)
    out << "  " << r.fit_outlier_samples
        << " marker samples were left out of their frame's solve as outliers (and of the "
           "figures), as fabrik solve leaves them out\n";
  // A built rest posture (keypoint templates) has no static trial to be compared with.
  if (!r.built_rest)
    out << "Rest posture vs static means: worst marker " << fmt("%.4f", r.rest_max_m * 1e3)
        << " mm\n";
  return out.str();
}

}  // namespace fabrik::calib
