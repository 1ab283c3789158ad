#include "keypoint_calibration.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <sstream>

#include "common/quantile.hpp"

namespace fabrik::calib {

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

std::string mm_text(double m) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", m * 1e3);
  return buf;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return kNan;
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h), v.end());
  if (v.size() % 2) return v[h];
  const double upper = v[h];
  return 0.5 * (upper + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h)));
}

class KeypointCalibrator {
 public:
  KeypointCalibrator(const CalibTemplate& t, const io::MarkerTrial& trial, std::string name)
      : t_(t), trial_(trial), name_(std::move(name)) {
    if (t_.kind != TemplateKind::keypoints)
      fail(t_.file + " is a marker template", "calibrate it with --static; --trial is for "
           "keypoint templates (\"kind\": \"keypoints\")");
  }

  // The template's own rest vectors, at their nominal lengths: the truth model of a
  // synthetic trial. `trial_` is a one-frame trial labelled with the template's keypoints.
  KeypointCalibration run_nominal(const std::optional<LabAxesSpec>& lab_axes) {
    // A nominal model keeps its optional keypoints.
    match_columns();
    first_ = 0;
    count_ = 1;
    jitter_.assign(t_.markers.size(), 0.0);
    length_m_.assign(t_.points.size(), kNan);
    for (std::size_t i = 0; i < t_.points.size(); ++i)
      if (t_.points[i].has_rest) length_m_[i] = t_.points[i].rest_m.norm();
    KeypointCalibrateOptions o;
    o.lab_axes = lab_axes ? lab_axes : t_.lab_axes;
    if (!o.lab_axes) o.lab_axes = LabAxesSpec{Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitX()};
    choose_axes(o);
    how_ = "declared (a nominal model)";
    nominal_ = true;
    return build();
  }

  KeypointCalibration run(const KeypointCalibrateOptions& o) {
    drop_absent_optional();
    match_columns();
    choose_window(o);
    estimate_jitter();
    measure_lengths(o);
    choose_axes(o);
    return build();
  }

 private:
  [[noreturn]] void fail(const std::string& problem, const std::string& fix) const {
    throw CalibrationError(name_ + ": " + problem + (fix.empty() ? "" : ". Fix: " + fix));
  }

  // A template keypoint matches a label exactly, or a "Subject:name" label.
  int column_of(const std::string& keypoint) const {
    if (const int c = trial_.find(keypoint); c >= 0) return c;
    int found = -1;
    for (std::size_t l = 0; l < trial_.labels.size(); ++l) {
      const std::string& lab = trial_.labels[l];
      if (lab.size() > keypoint.size() + 1 &&
          lab.compare(lab.size() - keypoint.size(), keypoint.size(), keypoint) == 0 &&
          lab[lab.size() - keypoint.size() - 1] == ':') {
        if (found >= 0)
          fail("keypoint '" + keypoint + "' matches both '" + trial_.labels[found] + "' and '" +
                   lab + "'",
               "track one subject per calibration");
        found = static_cast<int>(l);
      }
    }
    return found;
  }

  // An optional keypoint the trial lacks leaves the template with its point, unless
  // something is defined from that point.
  void drop_absent_optional() {
    for (std::size_t i = 0; i < t_.points.size();) {
      const PointDef& d = t_.points[i];
      if (!d.optional || d.target.empty() || column_of(d.refs[0].names[0]) >= 0) {
        ++i;
        continue;
      }
      for (const PointDef& other : t_.points) {
        bool uses = other.rest_from == d.name;
        for (const PointRef& r : other.refs)
          for (const std::string& n : r.names) uses = uses || n == d.name;
        if (uses)
          fail("optional keypoint '" + d.refs[0].names[0] + "' is absent, and point '" +
                   other.name + "' is defined from it",
               "make it required in " + t_.file + ", or define '" + other.name +
                   "' from other points");
      }
      for (const SegmentDef& s : t_.segments)
        if (s.base == d.name)
          fail("optional keypoint '" + d.refs[0].names[0] + "' is absent, and segment '" +
                   s.name + "' is based on it",
               "make it required in " + t_.file);
      absent_.push_back(d.refs[0].names[0]);
      const int m = t_.find_marker(d.refs[0].names[0]);
      t_.markers.erase(t_.markers.begin() + m);
      t_.points.erase(t_.points.begin() + static_cast<std::ptrdiff_t>(i));
    }
  }

  void match_columns() {
    column_.assign(t_.markers.size(), -1);
    std::string absent;
    for (std::size_t m = 0; m < t_.markers.size(); ++m) {
      column_[m] = column_of(t_.markers[m].name);
      if (column_[m] < 0 && !t_.markers[m].static_only) absent += (absent.empty() ? "" : ", ") + t_.markers[m].name;
    }
    if (!absent.empty())
      fail("the trial lacks keypoints the template needs: " + absent,
           "use a trial with these keypoint names (" + t_.file +
               " follows the names its tool writes), or mark them \"optional\" in the template");
  }

  void choose_window(const KeypointCalibrateOptions& o) {
    if (trial_.frames() == 0) fail("the trial has no frames", "give a few seconds of movement");
    const FrameWindow w = frame_window(trial_, name_, o.first_frame, o.frames);
    first_ = w.first;
    count_ = w.count;
  }

  // Per keypoint, per axis: white jitter of sd s makes the second difference's sd s*sqrt(6),
  // while smooth movement adds little to it at a camera's frame rate (a 10 m/s^2
  // acceleration at 60 Hz adds 3 mm). The MAD keeps swaps and jumps out of it.
  void estimate_jitter() {
    jitter_.assign(t_.markers.size(), 0.0);
    for (std::size_t m = 0; m < t_.markers.size(); ++m) {
      if (column_[m] < 0) continue;  // a fixed point's marker: never seen
      const auto c = static_cast<std::size_t>(column_[m]);
      std::vector<double> d2;
      for (std::size_t f = first_ + 1; f + 1 < first_ + count_; ++f) {
        const Eigen::Vector3d a = trial_.at(f - 1, c), b = trial_.at(f, c), e = trial_.at(f + 1, c);
        if (!a.allFinite() || !b.allFinite() || !e.allFinite()) continue;
        const Eigen::Vector3d s = a - 2.0 * b + e;
        for (int k = 0; k < 3; ++k) d2.push_back(s[k]);
      }
      if (d2.size() < 30) continue;
      const double med = median_of(d2);
      for (double& v : d2) v = std::abs(v - med);
      jitter_[m] = 1.4826 * median_of(d2) / std::sqrt(6.0);
    }
  }

  // Where the point is in frame f of the trial (NaN if a keypoint it needs is missing).
  Eigen::Vector3d position(const std::string& name, std::size_t f) const {
    if (const int m = t_.find_marker(name); m >= 0)
      return column_[m] < 0 ? Eigen::Vector3d::Constant(kNan)
                            : trial_.at(f, static_cast<std::size_t>(column_[m]));
    const PointDef& d = t_.points[t_.find_point(name)];
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    std::size_t n = 0;
    for (const PointRef& r : d.refs)
      for (const std::string& ref : r.names) {
        sum += position(ref, f);
        ++n;
      }
    return sum / static_cast<double>(n);  // NaN propagates
  }

  // A position as a weighted sum of keypoints (keypoint -> weight): a keypoint's, or a mean's.
  void add_weights(const std::string& name, double w, std::map<int, double>& out) const {
    if (const int m = t_.find_marker(name); m >= 0) {
      out[m] += w;
      return;
    }
    const PointDef& d = t_.points[t_.find_point(name)];
    std::size_t n = 0;
    for (const PointRef& r : d.refs) n += r.names.size();
    for (const PointRef& r : d.refs)
      for (const std::string& ref : r.names) add_weights(ref, w / static_cast<double>(n), out);
  }

  // The jitter variance (per axis) of the difference of two positions: a keypoint shared by
  // both (a hip and the hips' midpoint) cancels in part.
  double difference_jitter_var(const std::string& a, const std::string& b) const {
    std::map<int, double> w;
    add_weights(a, 1.0, w);
    add_weights(b, -1.0, w);
    double var = 0.0;
    for (const auto& [m, c] : w) var += c * c * jitter_[static_cast<std::size_t>(m)] * jitter_[static_cast<std::size_t>(m)];
    return var;
  }

  std::string rest_from(const PointDef& d) const {
    return d.rest_from.empty() ? t_.segments[d.segment].base : d.rest_from;
  }

  void measure_lengths(const KeypointCalibrateOptions& o) {
    length_m_.assign(t_.points.size(), kNan);
    for (std::size_t i = 0; i < t_.points.size(); ++i) {
      const PointDef& d = t_.points[i];
      if (d.fixed) length_m_[i] = d.rest_m.norm();
      if (d.fixed || !d.has_rest || d.rest_m.norm() < 1e-9) continue;
      const std::string from = rest_from(d);
      std::vector<double> dist;
      for (std::size_t f = first_; f < first_ + count_; ++f) {
        const Eigen::Vector3d a = position(d.name, f), b = position(from, f);
        if (a.allFinite() && b.allFinite()) dist.push_back((a - b).norm());
      }
      if (dist.empty())
        fail("point '" + d.name + "' and '" + from + "' are never seen together in the window",
             "choose a window where both keypoints are present");
      KeypointLength l;
      l.segment = t_.segments[d.segment].name;
      l.point = d.name;
      l.from = from;
      l.samples = static_cast<int>(dist.size());
      l.median_raw_m = median_of(dist);
      l.iqr_m = quantile(dist, 0.75) - quantile(dist, 0.25);
      std::vector<double> dev;
      for (double x : dist) dev.push_back(std::abs(x - l.median_raw_m));
      l.mad_m = median_of(dev);
      // Jitter perpendicular to the segment lengthens it: E|L + n|^2 = L^2 + 3 var, of
      // which the two perpendicular axes survive in the median of |L + n|.
      const double var = difference_jitter_var(d.name, from);
      l.median_m = std::sqrt(std::max(0.0, l.median_raw_m * l.median_raw_m - 2.0 * var));
      l.wide = l.iqr_m > std::max(o.wide_spread_share * l.median_m, o.wide_spread_min_m);
      length_m_[i] = l.median_m;
      lengths_.push_back(l);
    }
  }

  // Declared, else up detected: the lab axis nearest the mean measured direction of the
  // points whose rest vector is vertical (legs, trunk, neck), sign by the rest's.
  void choose_axes(const KeypointCalibrateOptions& o) {
    const std::optional<LabAxesSpec>& declared = o.lab_axes ? o.lab_axes : t_.lab_axes;
    const auto nearest = nearest_lab_axis;
    // Mean measured directions of vertical and of anterior rest vectors.
    Eigen::Vector3d superior = Eigen::Vector3d::Zero(), anterior = Eigen::Vector3d::Zero();
    for (const PointDef& d : t_.points) {
      if (!d.has_rest || d.rest_m.norm() < 1e-9) continue;
      const Eigen::Vector3d dir = d.rest_m.normalized();
      const bool vertical = std::abs(dir.y()) > 0.9, front = std::abs(dir.x()) > 0.7;
      if (!vertical && !front) continue;
      const std::string from = rest_from(d);
      for (std::size_t f = first_; f < first_ + count_; ++f) {
        const Eigen::Vector3d v = position(d.name, f) - position(from, f);
        if (!v.allFinite() || v.norm() < 1e-9) continue;
        if (vertical) superior += (dir.y() > 0 ? 1.0 : -1.0) * v.normalized();
        if (front) anterior += (dir.x() > 0 ? 1.0 : -1.0) * v.normalized();
      }
    }
    Eigen::Vector3d up, forward;
    if (declared) {
      up = declared->up_lab;
      how_ = std::string(o.lab_axes ? "declared with --lab-up/--lab-forward"
                                    : "declared in the template");
      up_note_ = declared_up_note(up, superior,
                                  "the movement's superior direction (the keypoints' vertical "
                                  "segments: trunk, legs)");
    } else if (superior.norm() > 1e-9) {
      up = nearest(superior, Eigen::Vector3d::Zero());
      how_ = "detected from the movement: up is the lab axis nearest the mean direction of the "
             "keypoints' vertical segments (trunk, legs)";
    } else {
      up = Eigen::Vector3d::UnitY();
      how_ = "assumed: no vertical segment to detect it from";
    }
    if (declared && declared->forward_lab) {
      forward = *declared->forward_lab;
    } else if (const std::optional<Eigen::Vector3d> f = default_forward_lab(up)) {
      forward = *f;
      how_ += "; forward is +x, which is horizontal";
    } else {
      forward = nearest(anterior - up * up.dot(anterior), up);
      how_ += "; forward is the horizontal lab axis nearest the keypoints' anterior directions";
    }
    axes_.col(0) = forward;
    axes_.col(1) = up;
    axes_.col(2) = forward.cross(up);
    lab_ = LabAxesSpec{up, forward};
  }

  // The rest position of a point in OpenSim's axes, relative to the root's base.
  Eigen::Vector3d rest_osim(const std::string& name, int depth = 0) {
    if (depth > 64) fail("the template's rest vectors form a cycle at '" + name + "'",
                         "define every \"rest_from\" without coming back to the point");
    if (const int m = t_.find_marker(name); m >= 0) {
      for (const PointDef& d : t_.points)
        if ((!d.target.empty() || d.fixed) && d.refs[0].names[0] == name)
          return rest_osim(d.name, depth + 1);
    }
    const int i = t_.find_point(name);
    const PointDef& d = t_.points[static_cast<std::size_t>(i)];
    if (d.segment == 0 && t_.segments[0].base == d.name) return Eigen::Vector3d::Zero();
    if (d.has_rest) {
      const Eigen::Vector3d from = rest_osim(rest_from(d), depth + 1);
      if (d.rest_m.norm() < 1e-9) return from;
      return from + d.rest_m.normalized() * length_m_[static_cast<std::size_t>(i)];
    }
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    std::size_t n = 0;
    for (const PointRef& r : d.refs)
      for (const std::string& ref : r.names) {
        sum += rest_osim(ref, depth + 1);
        ++n;
      }
    return sum / static_cast<double>(n);
  }

  KeypointCalibration build() {
    // The rest posture stands where the root's base was, on median.
    const std::string root_base = t_.segments[0].base;
    // A nominal model stands with its root 0.95 m up.
    Eigen::Vector3d root = 0.95 * axes_.col(1);
    for (int k = 0; k < 3 && !nominal_; ++k) {
      std::vector<double> v;
      for (std::size_t f = first_; f < first_ + count_; ++f)
        if (const Eigen::Vector3d p = position(root_base, f); p.allFinite()) v.push_back(p[k]);
      if (v.empty()) fail("the root's base '" + root_base + "' is never seen", "");
      root[k] = median_of(v);
    }
    // The rest posture as a one-frame trial labelled as the movement (so that the config maps
    // its labels), plus a column for each fixed point's marker.
    io::MarkerTrial rest;
    rest.labels = trial_.labels;
    std::vector<int> rest_column = column_;
    for (std::size_t m = 0; m < t_.markers.size(); ++m)
      if (rest_column[m] < 0) {
        rest_column[m] = static_cast<int>(rest.labels.size());
        rest.labels.push_back(t_.markers[m].name);
      }
    rest.rate_hz = trial_.rate_hz;
    rest.first_frame = 1;
    rest.positions_m.assign(rest.labels.size(), Eigen::Vector3d::Constant(kNan));
    for (std::size_t m = 0; m < t_.markers.size(); ++m)
      rest.at(0, static_cast<std::size_t>(rest_column[m])) =
          root + axes_ * rest_osim(t_.markers[m].name);

    BuiltRest built;
    built.axes_lab = axes_;
    built.fit_trial = nominal_ ? &rest : &trial_;  // nominal: the rest posture itself
    built.fit_first = first_;
    built.fit_count = count_;
    const long long first_no = trial_.first_frame + static_cast<long long>(first_);
    const long long last_no = first_no + static_cast<long long>(count_) - 1;
    built.source = nominal_ ? "the template's nominal lengths (a model for synthetic trials)."
                            : "segment lengths are medians over frames " +
                                  std::to_string(first_no) + " to " + std::to_string(last_no) +
                                  " of " + name_ +
                                  "; the rest posture is the template's standing posture at "
                                  "those lengths.";
    CalibrateOptions co;
    co.lab_axes = lab_;
    KeypointCalibration k;
    k.result = calibrate_built_rest(t_, rest, name_, co, built);
    k.result.first_frame = first_no;
    k.result.frames = static_cast<long long>(count_);
    k.result.lab_axes_how = how_;
    k.result.rest_max_m = 0.0;
    k.lengths = lengths_;
    for (std::size_t m = 0; m < t_.markers.size(); ++m)
      k.jitter_m.emplace_back(t_.markers[m].name, jitter_[m]);
    k.absent_optional = absent_;
    for (const std::string& a : absent_)
      k.result.notes.push_back("optional keypoint '" + a + "' is not in the trial: not tracked");
    if (up_note_) k.result.notes.push_back(*up_note_);
    return k;
  }

  CalibTemplate t_;  // a copy: absent optional keypoints are dropped from it
  const io::MarkerTrial& trial_;
  std::string name_;
  std::vector<int> column_;     // per template marker (keypoint): trial column
  std::vector<double> jitter_;  // per template marker: per-axis jitter sd, m
  std::size_t first_ = 0, count_ = 0;
  std::vector<double> length_m_;  // per template point with a rest vector
  std::vector<KeypointLength> lengths_;
  std::vector<std::string> absent_;
  Eigen::Matrix3d axes_ = Eigen::Matrix3d::Identity();
  bool nominal_ = false;
  LabAxesSpec lab_;
  std::string how_;
  std::optional<std::string> up_note_;  // a declared up axis far from the measured one
};

}  // namespace

KeypointCalibration calibrate_keypoints(const CalibTemplate& tmpl, const io::MarkerTrial& trial,
                                        const std::string& trial_name,
                                        const KeypointCalibrateOptions& options) {
  return KeypointCalibrator(tmpl, trial, trial_name).run(options);
}

KeypointCalibration nominal_keypoint_model(const CalibTemplate& tmpl,
                                           const std::optional<LabAxesSpec>& lab_axes) {
  io::MarkerTrial names;
  for (const MarkerDef& m : tmpl.markers) names.labels.push_back(m.name);
  names.rate_hz = 100.0;
  names.positions_m.assign(names.labels.size(), Eigen::Vector3d::Constant(kNan));
  return KeypointCalibrator(tmpl, names, "<nominal lengths>").run_nominal(lab_axes);
}

std::string keypoint_length_report(const KeypointCalibration& k) {
  std::ostringstream out;
  if (k.lengths.empty()) {  // --nominal: no trial measured them
    out << "Segment lengths: the template's nominal ones (no trial)\n";
    return out.str();
  }
  out << "Length window: frames " << k.result.first_frame << " to "
      << k.result.first_frame + k.result.frames - 1 << " (" << k.result.frames
      << " frames of movement; no static trial)\n"
      << "Segment lengths from the keypoints (median over the window; corrected: less the "
         "keypoints' jitter, which lengthens a distance; spread: IQR and MAD of the per-frame "
         "distance)\n"
      << "  segment        point            from               median  corrected    IQR    MAD"
         "  frames\n";
  int wide = 0;
  for (const KeypointLength& l : k.lengths) {
    char line[256];
    std::snprintf(line, sizeof line, "  %-14s %-16s %-16s %8.1f %10.1f %6.1f %6.1f %7d%s\n",
                  l.segment.c_str(), l.point.c_str(), l.from.c_str(), l.median_raw_m * 1e3,
                  l.median_m * 1e3, l.iqr_m * 1e3, l.mad_m * 1e3, l.samples,
                  l.wide ? "  WIDE" : "");
    out << line;
    wide += l.wide;
  }
  if (wide)
    out << "  " << wide << " length(s) marked WIDE: their IQR is over 10 % of the length (at "
           "least 15 mm): noisy or swapping keypoints; check them, or choose a cleaner window "
           "(--first-frame/--frames)\n";
  double worst = 0.0;
  std::string worst_name;
  for (const auto& [name, j] : k.jitter_m)
    if (j > worst) {
      worst = j;
      worst_name = name;
    }
  out << "Keypoint jitter (per axis, from second differences): worst " << mm_text(worst)
      << " mm (" << (worst_name.empty() ? "-" : worst_name) << ")\n\n";
  return out.str();
}

nlohmann::ordered_json keypoint_lengths_json(const KeypointCalibration& k) {
  nlohmann::ordered_json lengths = nlohmann::ordered_json::array();
  for (const KeypointLength& l : k.lengths)
    lengths.push_back({{"segment", l.segment}, {"point", l.point}, {"from", l.from},
                       {"median_raw_mm", l.median_raw_m * 1e3}, {"median_mm", l.median_m * 1e3},
                       {"iqr_mm", l.iqr_m * 1e3}, {"mad_mm", l.mad_m * 1e3},
                       {"frames", l.samples}, {"wide", l.wide}});
  nlohmann::ordered_json jitter = nlohmann::ordered_json::object();
  for (const auto& [name, j] : k.jitter_m) jitter[name] = j * 1e3;
  return {{"first_frame", k.result.first_frame}, {"frames", k.result.frames},
          {"lengths", lengths}, {"jitter_mm", jitter}, {"absent_optional", k.absent_optional}};
}

}  // namespace fabrik::calib
