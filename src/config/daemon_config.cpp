#include "daemon_config.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <map>

#include "common/ascii_case.hpp"
#include "endpoint_check.hpp"
#include "json_reader.hpp"
#include "lab_axes_json.hpp"
#include "model_loader.hpp"
#include "resources.hpp"
#include "sensors_json.hpp"
#include "solver_options_json.hpp"
#include "tracking_options_json.hpp"

namespace fabrik {

namespace {

constexpr const char* kFormat = "fabrikd-config/1";
constexpr const char* kEmbeddedDefault = "<embedded>/default.json";

// A model path is relative to the config file's folder; the embedded
// models/*.json resolve when no such file exists (and always for the
// embedded default, so it never depends on the working directory).
Model read_model(const JsonReader& model, const std::string& config_file) {
  if (model.value().is_object()) return load_model(model);
  const std::string name = model.as_string();
  if (name.empty())  // else the config's own folder, "a directory"
    model.fail("the model's path is empty",
               "give a path relative to the config file, an embedded model "
               "(models/fullbody.json, models/paper_upper_body.json) or the model object itself");
  std::filesystem::path path(name);
  if (config_file != kEmbeddedDefault && path.is_relative())
    path = std::filesystem::path(config_file).parent_path() / path;
  std::error_code ec;
  if (config_file != kEmbeddedDefault &&
      std::filesystem::symlink_status(path, ec).type() != std::filesystem::file_type::not_found) {
    std::string text;
    if (auto p = read_text_file(path.string(), text))
      model.fail("model file '" + path.string() + "' " +
                     (p->problem.rfind("is ", 0) == 0 ? p->problem : "cannot be used: " + p->problem),
                 p->fix);
    return load_model(JsonReader::parse(text, path.string()), path.string());
  }
  if (auto text = embedded_config(name)) return load_model(JsonReader::parse(*text, name), name);
  model.fail("model file '" + path.string() + "' not found",
             "give a path relative to the config file, an embedded model (models/fullbody.json, "
             "models/paper_upper_body.json) or the model object itself");
}

Endpoint read_endpoint(const JsonReader& r, Endpoint e) {
  if (r.has("mode"))
    e.mode =
        read_choice<SocketMode>(r.at("mode"), "socket mode",
                                {{"bind", SocketMode::bind}, {"connect", SocketMode::connect}});
  if (r.has("endpoint")) {
    e.address = r.at("endpoint").as_string();
    if (auto p = endpoint_problem(e.address, e.mode)) r.at("endpoint").fail(p->problem, p->fix);
  }
  return e;
}

void read_targets(const JsonReader& targets, const Model& model, std::vector<MarkerTarget>& out,
                  bool has_sensors) {
  targets.only_keys({"default", "markers"});
  MarkerTarget base;
  if (targets.has("default")) {
    const JsonReader d = targets.at("default");
    d.only_keys({"level", "weight"});
    base.level = static_cast<int>(d.get("level", 0LL, -1000LL, 1000LL));
    base.weight = d.get("weight", 1.0, 1e-9, 1e9);
  }
  // Every model marker under its own name, unless an entry says otherwise.
  std::map<std::string, MarkerTarget> by_name;
  std::vector<std::string> order;
  for (int p : model.marker_points()) {
    MarkerTarget t = base;
    t.marker = model.points[p].name;
    t.point = p;
    by_name[t.marker] = t;
    order.push_back(t.marker);
  }
  if (targets.has("markers")) {
    const JsonReader markers = targets.at("markers");
    markers.expect_object();
    // Each target costs the gap predictor per pair of targets: the model's limit holds here too.
    if (markers.value().size() > ModelLimits::kMarkers)
      markers.fail("the config lists " + std::to_string(markers.value().size()) +
                       " marker targets; fabrikd takes at most " +
                       std::to_string(ModelLimits::kMarkers),
                   "list only the markers the stream sends");
    std::vector<std::string> dropped;
    for (auto it = markers.value().begin(); it != markers.value().end(); ++it) {
      const JsonReader e = markers.at(it.key());
      e.only_keys({"point", "level", "weight", "track"});
      MarkerTarget t = by_name.count(it.key()) ? by_name[it.key()] : base;
      t.marker = it.key();
      if (e.has("point")) {
        const std::string point = e.at("point").as_string();
        t.point = model.find_point(point);
        if (t.point < 0)
          e.at("point").fail("the model has no point '" + point + "'",
                             "name one of the model's markers or joint points");
        // The stream name takes the place of the point's own name.
        if (point != it.key() && by_name.count(point)) dropped.push_back(point);
      } else if (t.point < 0) {
        e.fail("'" + it.key() + "' is not a marker of the model",
               "add \"point\": the model point this marker pulls, or fix the name");
      }
      t.level = static_cast<int>(e.get("level", static_cast<long long>(t.level), -1000LL, 1000LL));
      t.weight = e.get("weight", t.weight, 1e-9, 1e9);
      if (!by_name.count(t.marker)) order.push_back(t.marker);
      by_name[t.marker] = t;
      if (!e.get("track", true)) dropped.push_back(t.marker);
    }
    for (const std::string& name : dropped) {
      by_name.erase(name);
      order.erase(std::remove(order.begin(), order.end(), name), order.end());
    }
  }
  if (order.size() > ModelLimits::kMarkers)
    targets.fail("the config tracks " + std::to_string(order.size()) +
                     " markers; fabrikd takes at most " + std::to_string(ModelLimits::kMarkers),
                 "track fewer markers (\"track\": false)");
  for (const std::string& name : order) out.push_back(by_name[name]);
  if (out.empty() && !has_sensors)
    targets.fail("no marker is tracked",
                 "keep at least one model marker with \"track\": true, or add \"sensors\"");
}

// Gap filling from the recent past (PredictionSettings): on unless switched off, by default
// on the weakest marker level with a small weight (docs/gap-filling.md).
PredictionSettings read_prediction(const JsonReader& root, int default_level) {
  PredictionSettings p;
  p.enabled = true;
  p.level = default_level;
  if (!root.has("prediction")) return p;
  const JsonReader r = root.at("prediction");
  r.only_keys({"enabled", "level", "weight", "velocity_decay_s", "velocity_window_s",
               "return_speed_mm_per_s", "donors", "donor_max_joints"});
  p.enabled = r.get("enabled", p.enabled);
  p.level = static_cast<int>(r.get("level", static_cast<long long>(p.level), -1001LL, 1000LL));
  p.weight = r.get("weight", p.weight, 1e-9, 1e9);
  p.velocity_decay_s = r.get("velocity_decay_s", p.velocity_decay_s, 0.0, 10.0);
  p.velocity_window_s = r.get("velocity_window_s", p.velocity_window_s, 0.0, 1.0);
  p.return_speed_m_per_s =
      r.get("return_speed_mm_per_s", p.return_speed_m_per_s * 1e3, 1.0, 1e6) * 1e-3;
  p.donors = r.get("donors", p.donors);
  p.donor_max_joints = static_cast<int>(
      r.get("donor_max_joints", static_cast<long long>(p.donor_max_joints), 0LL, 100LL));
  return p;
}


// The model, targets, sensors, solver, occlusion and tracking options: one subject's tracking.
void read_tracking_parts(const JsonReader& root, const std::string& file, DaemonConfig& c) {
  auto model = std::make_shared<const Model>(read_model(root.at("model"), file));
  if (root.has("sensors")) {
    std::vector<std::string> segments;
    for (const Segment& seg : model->segments) segments.push_back(seg.name);
    c.sensors = read_sensor_section(root.at("sensors"), segments, true);
    resolve_world_up(root.at("sensors"), c.sensors, model->lab_axes.up_lab);
    c.tracker.sensors = sensor_setup(c.sensors, *model);
  }
  const bool has_sensors = !c.tracker.sensors.sensors.empty();
  read_targets(root.has("targets") ? root.at("targets")
                                   : JsonReader(nlohmann::json::object(), file, "/targets"),
               *model, c.tracker.markers, has_sensors);
  c.tracker.model = model;

  if (root.has("solver")) c.tracker.solver = read_solver_options(root.at("solver"), c.tracker.solver);

  int weakest = 1000;
  for (const MarkerTarget& t : c.tracker.markers) weakest = std::min(weakest, t.level);
  for (const SensorTarget& t : c.tracker.sensors.sensors) weakest = std::min(weakest, t.level);
  c.tracker.occlusion.hold_level = weakest - 1;
  if (root.has("occlusion")) {
    const JsonReader o = root.at("occlusion");
    o.only_keys({"hold_s", "hold_level"});
    c.tracker.occlusion.hold_s = o.get("hold_s", c.tracker.occlusion.hold_s, 0.0, 3600.0);
    c.tracker.occlusion.hold_level = static_cast<int>(o.get(
        "hold_level", static_cast<long long>(c.tracker.occlusion.hold_level), -1001LL, 1000LL));
  }
  read_tracking_options(root, c.tracker);
  c.tracker.prediction = read_prediction(root, weakest);
}

// input, output: the daemon's sockets and encodings.
void read_io_parts(const JsonReader& root, DaemonConfig& c) {
  if (root.has("input")) {
    const JsonReader in = root.at("input");
    in.only_keys({"endpoint", "mode", "units", "max_payload_bytes", "max_backlog_frames",
                  "max_abs_coordinate_mm", "zero_is_missing", "quaternion_tolerance", "source",
                  "source_options"});
    c.input = read_endpoint(in, c.input);
    c.source = read_source_config(in);
    if (in.has("units")) c.input_m_per_unit = metres_per_unit(in.at("units"));
    c.max_payload_bytes = static_cast<std::size_t>(
        in.get("max_payload_bytes", static_cast<long long>(c.max_payload_bytes), 64LL, 1LL << 30));
    c.max_backlog_frames = static_cast<int>(
        in.get("max_backlog_frames", static_cast<long long>(c.max_backlog_frames), 1LL, 10000LL));
    c.max_abs_coordinate_m =
        in.get("max_abs_coordinate_mm", c.max_abs_coordinate_m * 1e3, 1.0, 1e9) * 1e-3;
    c.zero_is_missing = in.get("zero_is_missing", c.zero_is_missing);
    c.quaternion_tolerance =
        in.get("quaternion_tolerance", c.quaternion_tolerance, 1e-9, 0.5);
  }
  if (root.has("output")) {
    const JsonReader out = root.at("output");
    out.only_keys({"endpoint", "mode", "encoding", "units", "measured_markers", "pose_content",
                   "views"});
    c.output = read_endpoint(out, c.output);
    if (out.has("units")) {
      c.output_m_per_unit = metres_per_unit(out.at("units"));
      c.output_units = out.at("units").as_string();
    }
    if (out.has("encoding"))
      c.output_encoding =
          read_choice<Encoding>(out.at("encoding"), "encoding",
                                {{"json", Encoding::json}, {"msgpack", Encoding::msgpack}});
    c.output_measured_markers = out.get("measured_markers", c.output_measured_markers);
    if (out.has("pose_content")) c.output_pose_content = read_pose_content(out.at("pose_content"));
    if (out.has("views"))
      c.output_views = read_pose_views(out.at("views"), c.output_encoding, c.output_units);
  }
  if (endpoints_clash(c.input, c.output)) {
    // Where the clash is written: at the output's endpoint, or at the input when the output's
    // is the default.
    const std::string same = "'" + c.input.address + "'" + clash_spelling(c.input, c.output);
    if (root.has("output") && root.at("output").has("endpoint"))
      root.at("output").fail("input and output use the same endpoint " + same,
                             "give the pose output its own endpoint");
    root.at("input").fail("the input's endpoint " + same + " is the pose output's default",
                          "give the input another endpoint, or the output one of its own "
                          "(\"output\": {\"endpoint\": ...})");
  }
}


// `subjects`: each entry's name and its own config file (what `fabrik
// calibrate` writes), of which the tracking parts are used.
void read_subjects(const JsonReader& list, const std::string& file,
                   std::vector<SubjectConfig>& out) {
  list.expect_array();
  const std::size_t n = list.value().size();
  if (n == 0 || n > kMaxSubjects)
    list.fail("\"subjects\" lists " + std::to_string(n) + " subjects",
              "list 1 to " + std::to_string(kMaxSubjects) + " subjects (or leave the key out "
              "for one subject)");
  for (std::size_t k = 0; k < n; ++k) {
    const JsonReader e = list.at(k);
    e.only_keys({"name", "config"});
    SubjectConfig s;
    s.name = e.at("name").as_string();
    const bool name_ok =
        !s.name.empty() && s.name.size() <= kMaxSubjectNameBytes &&
        std::all_of(s.name.begin(), s.name.end(), [](char ch) {
          return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-' ||
                 ch == '.';
        });
    if (!name_ok)
      e.at("name").fail("subject name '" + s.name + "' cannot be used",
                        "use 1 to " + std::to_string(kMaxSubjectNameBytes) +
                            " letters, digits, '_', '-' or '.' (it becomes the topic pose/NAME "
                            "and the prefix NAME: of marker names)");
    for (const SubjectConfig& other : out) {
      if (other.name == s.name)
        e.at("name").fail("subject '" + s.name + "' is listed twice", "give each subject its own name");
      // ZeroMQ matches topics by prefix: a subscriber of pose/P1 would get pose/P12's poses.
      if (other.name.starts_with(s.name) || s.name.starts_with(other.name))
        e.at("name").fail("subjects '" + other.name + "' and '" + s.name +
                              "' start alike: a subscriber of pose/" +
                              (s.name.size() < other.name.size() ? s.name : other.name) +
                              " would receive both subjects' poses (topics match by prefix)",
                          "give each subject a name that is not the start of another's (P01 "
                          "and P12, not P1 and P12)");
    }
    std::filesystem::path path(e.at("config").as_string());
    if (path.is_relative() && file != kEmbeddedDefault)
      path = std::filesystem::path(file).parent_path() / path;
    std::string text;
    if (auto p = read_text_file(path.string(), text))
      e.at("config").fail("subject config '" + path.string() + "' " +
                              (p->problem.rfind("is ", 0) == 0 ? p->problem
                                                              : "cannot be used: " + p->problem),
                          p->fix.empty() ? "give a path relative to this config" : p->fix);
    if (nlohmann::json::parse(text, nullptr, false).contains("subjects"))
      e.at("config").fail("subject config '" + path.string() + "' lists subjects itself",
                          "name the config of one subject (what fabrik calibrate writes)");
    DaemonConfig one = load_daemon_config(text, path.string());
    const std::string shared = unprefix_subject_targets(one.tracker, s.name);
    if (!shared.empty())
      e.at("config").fail("subject config '" + path.string() + "' has targets '" + s.name + ":" +
                              shared + "' and '" + shared + "'",
                          "keep one of them: the stream's '" + s.name + ":" + shared +
                              "' reaches subject " + s.name + " as '" + shared + "'");
    // Listed as 'daphnee', targets named 'Daphnee:X' (calibrated from the stream's names) are
    // reached by no name of the stream: names are case-sensitive.
    for (const MarkerTarget& m : one.tracker.markers) {
      const std::size_t colon = m.marker.find(':');
      const std::string_view prefix = std::string_view(m.marker).substr(0, colon);
      if (colon != std::string::npos && prefix != s.name && iequals(prefix, s.name))
        e.at("name").fail("subject '" + s.name + "' has targets named '" + m.marker +
                              "': the stream's '" + std::string(prefix) +
                              ":' names would reach no subject (names are case-sensitive)",
                          "name the subject '" + std::string(prefix) + "', as the stream does");
    }
    s.file = path.string();
    s.tracker = std::move(one.tracker);
    s.sensors = std::move(one.sensors);
    out.push_back(std::move(s));
  }
}

// A model or a template given where a config belongs is named for what it is, before its
// fields are refused one by one as a config's unknown ones.
void refuse_other_formats(const JsonReader& root) {
  const bool has_format = root.has("format") && root.at("format").value().is_string();
  const std::string format = has_format ? root.at("format").as_string() : std::string();
  const bool model =
      format.starts_with("fabrikd-model/") || (!root.has("format") && root.has("segments"));
  if (model)
    (has_format ? root.at("format") : root)
        .fail(std::string("this is a model, not a daemon config (") + kFormat + ")",
              "give it as a config's \"model\" (docs/models.md), or give a daemon config");
  if (format.starts_with("fabrikd-template/"))
    root.at("format").fail(
        std::string("this is a model template, not a daemon config (") + kFormat + ")",
        "calibrate it into one: fabrik calibrate --template FILE --static "
        "TRIAL --output CONFIG");
}

}  // namespace

std::string unprefix_subject_targets(TrackerSetup& tracker, std::string_view subject) {
  const std::string prefix = std::string(subject) + ":";
  std::vector<std::string> names;
  names.reserve(tracker.markers.size());
  for (const MarkerTarget& t : tracker.markers)
    names.push_back(t.marker.size() > prefix.size() && t.marker.starts_with(prefix)
                        ? t.marker.substr(prefix.size())
                        : t.marker);  // "NAME:" alone names nothing the stream sends: kept
  std::vector<std::string> sorted = names;
  std::sort(sorted.begin(), sorted.end());
  if (const auto twice = std::adjacent_find(sorted.begin(), sorted.end()); twice != sorted.end())
    return *twice;
  for (std::size_t i = 0; i < names.size(); ++i) tracker.markers[i].marker = std::move(names[i]);
  return {};
}

DaemonConfig load_daemon_config(const std::string& text, const std::string& file) {
  const nlohmann::json doc = JsonReader::parse(text, file);
  const JsonReader root(doc, file);
  root.expect_object();
  refuse_other_formats(root);
  const bool multi = root.has("subjects");
  if (multi)  // the tracking parts come from each subject's own config
    root.only_keys({"format", "description", "subjects", "subject_timeout_s", "input", "output",
                    "stats_interval_s", "log_level"});
  else
    root.only_keys({"format", "description", "model", "targets", "sensors", "solver", "input",
                    "output", "occlusion", "outliers", "quality", "cold_start", "prediction",
                    "confidence", "smoothing", "stats_interval_s", "log_level"});
  if (root.at("format").as_string() != kFormat)
    root.at("format").fail("unsupported format '" + root.at("format").as_string() + "'",
                           std::string("use \"") + kFormat + "\"");
  DaemonConfig c;
  c.file = file;
  c.description = root.get("description", std::string());
  if (multi) {
    read_subjects(root.at("subjects"), file, c.subjects);
    c.tracker = c.subjects.front().tracker;
    c.sensors = c.subjects.front().sensors;
    c.subject_timeout_s = root.get("subject_timeout_s", c.subject_timeout_s, 1e-3, 3600.0);
  } else {
    read_tracking_parts(root, file, c);
  }
  read_io_parts(root, c);
  if (const auto p = source_lab_problem(c))
    root.at("subjects").at(p->subject).at("config").fail(p->problem, p->fix);
  c.stats_interval_s = root.get("stats_interval_s", c.stats_interval_s, 0.01, 1.0);
  if (root.has("log_level")) {
    c.log_level = root.at("log_level").as_string();
    read_choice<int>(
        root.at("log_level"), "log level",
        {{"trace", 0}, {"debug", 1}, {"info", 2}, {"warn", 3}, {"error", 4}, {"off", 6}});
  }
  return c;
}

std::optional<SubjectLabProblem> source_lab_problem(const DaemonConfig& c) {
  if (c.subjects.empty() || c.source.kind == SourceKind::none) return std::nullopt;
  const SubjectConfig& first = c.subjects.front();
  for (std::size_t k = 1; k < c.subjects.size(); ++k) {
    const SubjectConfig& s = c.subjects[k];
    if (s.tracker.model->lab_axes == first.tracker.model->lab_axes) continue;
    return SubjectLabProblem{
        k,
        "subject " + s.name + "'s lab axes " + lab_axes_json(s.tracker.model->lab_axes).dump() +
            " are not subject " + first.name + "'s " +
            lab_axes_json(first.tracker.model->lab_axes).dump() +
            ", and the source's frames are turned into one lab's axes",
        "calibrate every subject in the lab's axes (fabrik calibrate --lab-up/--lab-forward, or "
        "the template's lab_axes; a subject config's own model: its lab_axes), or send the "
        "frames to the ZeroMQ input"};
  }
  return std::nullopt;
}

DaemonConfig load_daemon_config_file(const std::string& path) {
  return load_daemon_config(read_config_text(path), path);
}

DaemonConfig default_daemon_config() {
  return load_daemon_config(std::string(*embedded_config("default.json")), kEmbeddedDefault);
}

}  // namespace fabrik
