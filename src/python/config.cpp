// Loading a daemon config (or a bare model, tracked with the default config's settings) and
// calibrating a subject from a template and a static trial, as `fabrik calibrate` does.
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "bindings.hpp"
#include "calib/calibrate.hpp"
#include "config/json_reader.hpp"
#include "config/lab_axes_json.hpp"
#include "config/resources.hpp"
#include "io/marker_trial.hpp"
#include "io/output_file.hpp"

namespace fabrik::python {

namespace {

constexpr const char* kDefaultFile = "<embedded>/default.json";

// A file on disk by its absolute path, taken now (pickling sends it); a name that is no file
// (an embedded config, "<calibrated ...>") as it is.
std::string absolute_if_on_disk(const std::string& file) {
  std::error_code ec;
  if (file.empty() || !std::filesystem::exists(file, ec)) return file;
  const std::filesystem::path absolute = std::filesystem::absolute(file, ec);
  return ec ? file : absolute.string();
}

Config make_config(const std::string& text, const std::string& file) {
  return Config{std::make_shared<const DaemonConfig>(load_daemon_config(text, file)), text, "",
                absolute_if_on_disk(file)};
}

// A fabrikd-model/1 file is tracked with the embedded default config's settings (targets,
// solver, occlusion) and this model; anything else loads as a fabrikd-config/1 file.
Config load(const std::optional<std::string>& path) {
  if (!path) return make_config(std::string(*embedded_config("default.json")), kDefaultFile);
  if (!embedded_config(*path)) require_file(*path, "config");
  const std::string text = read_config_text(*path);
  const nlohmann::json doc = nlohmann::json::parse(text, nullptr, false);
  // A model says its format, or (the model loader takes it as optional) has segments and none.
  const bool model = doc.is_object() && (doc.contains("format") ? doc["format"] == "fabrikd-model/1"
                                                                : doc.contains("segments"));
  if (model) {
    nlohmann::ordered_json config =
        nlohmann::ordered_json::parse(std::string(*embedded_config("default.json")));
    config["description"] = "the embedded default's settings with the model " + *path;
    // A file on disk is given by its absolute path (it wins over an embedded model of the same
    // name, as read_config_text read it); an embedded model's name stays a name.
    config["model"] =
        std::filesystem::exists(*path) ? std::filesystem::absolute(*path).string() : *path;
    config["targets"].erase("markers");  // the default's pelvis names may not be this model's
    return make_config(config.dump(2) + "\n", *path);
  }
  return make_config(text, *path);
}

// Pickling (e.g. to send a config to Dask workers): the text and the file it came from, loaded
// again on the other side. A model path in the text resolves against that file's directory,
// so it must exist there too; calibrated configs carry their model inline.
py::tuple config_state(const Config& c) {
  return py::make_tuple(c.json, c.absolute_file, c.report);
}

Config config_from_state(const py::tuple& state) {
  if (state.size() != 3) throw std::invalid_argument("Config: not a pickled fabrik.Config");
  Config c = make_config(state[0].cast<std::string>(), state[1].cast<std::string>());
  c.report = state[2].cast<std::string>();
  return c;
}

// What `fabrik calibrate --template K --static S` says for a keypoint template, with the way
// out from Python: there is none in the module (no movement-trial calibration bound).
std::string keypoint_template_refusal(const std::string& template_path) {
  return calib::keypoint_template_not_static(template_path) +
         ", not from a static trial, and fabrik.calibrate calibrates marker templates only (the "
         "Python module has no keypoint calibration). Fix: fabrik calibrate --template " +
         template_path +
         " --trial MOVEMENT.trc --output subject.json (or --nominal instead of --trial), then "
         "fabrik.load_config(\"subject.json\")";
}

// The template's orientation sensors are not in the config fabrik.calibrate makes (the module
// does not calibrate sensors): said as the CLI says it, with the CLI's way to add them.
std::string sensors_left_out_note(std::size_t sensors) {
  return calib::sensors_left_out(sensors) +
         ": fabrik.calibrate does not calibrate sensors; calibrate them with `fabrik calibrate "
         "--static-orientations`";
}

Config calibrate(const std::string& template_path, const std::string& static_path,
                 const std::optional<std::string>& output, long long first_frame, long long frames,
                 long long auto_window, const std::string& lab_up, const std::string& lab_forward,
                 bool keep_zeros) {
  require_file(template_path, "template");
  require_file(static_path, "static trial");
  calib::CalibrateOptions options;
  options.first_frame = first_frame;
  options.frames = frames;
  options.auto_window = auto_window;
  if (!lab_up.empty()) {
    const nlohmann::json axes = lab_forward.empty()
                                    ? nlohmann::json{{"up", lab_up}}
                                    : nlohmann::json{{"up", lab_up}, {"forward", lab_forward}};
    options.lab_axes = read_lab_axes(JsonReader(axes, "lab_up/lab_forward"));
  } else if (!lab_forward.empty()) {
    throw std::invalid_argument("lab_forward needs lab_up: give both");
  }
  Config out;
  std::string sensors_note;  // warned once the GIL is held again
  {
    py::gil_scoped_release unlocked;  // reading, calibrating and checking take a while
    const calib::CalibTemplate tmpl = calib::load_template_file(template_path);
    // A keypoint template has no static trial: calibrate() would ask for its keypoints in the
    // "static" one and name a fix (a static trial with them) that cannot work.
    if (tmpl.kind == calib::TemplateKind::keypoints)
      throw calib::CalibrationError(keypoint_template_refusal(template_path));
    io::ReadOptions read;
    read.zeros_are_missing = !keep_zeros;
    const io::MarkerTrial trial = io::read_trial(static_path, read);
    io::require_marker_data(trial, static_path);
    calib::CalibrationResult r = calib::calibrate(tmpl, trial, static_path, options);
    if (!tmpl.sensors.entries.empty()) {
      // In the report's notes, as `fabrik calibrate` prints it without --static-orientations.
      sensors_note = sensors_left_out_note(tmpl.sensors.entries.size());
      r.notes.push_back(sensors_note);
    }
    out.json = r.config.dump(2) + "\n";
    out.report = calib::calibration_report(r);
    // The config loads as the daemon will load it before it is written (as `fabrik calibrate`).
    out.config = std::make_shared<const DaemonConfig>(
        load_daemon_config(out.json, output ? *output : "<calibrated " + static_path + ">"));
    if (output) {  // io::OutputFileError: Python's OSError (errors.cpp)
      std::ofstream file = io::open_output_file(*output);
      file << out.json;
      io::finish_output_file(file, *output);
    }
    out.absolute_file = absolute_if_on_disk(out.config->file);
  }
  // stacklevel 2: the line that called fabrik.calibrate (1 is fabrik/config.py's wrapper).
  if (!sensors_note.empty() && PyErr_WarnEx(PyExc_UserWarning, sensors_note.c_str(), 2) != 0)
    throw py::error_already_set();  // warnings turned into errors
  return out;
}

std::vector<std::string> coordinate_names(const Model& model, CoordinateKind kind) {
  std::vector<std::string> names;
  for (const Coordinate& c : model.coordinates)
    if (c.kind == kind) names.push_back(c.name);
  return names;
}

}  // namespace

void bind_config(py::module_& m) {
  py::class_<Config>(m, "Config",
                     "A daemon config (fabrikd-config/1): the model, the tracked markers and "
                     "their priorities, the solver and occlusion settings. Immutable.")
      .def_property_readonly("file", [](const Config& c) { return c.config->file; })
      .def_property_readonly("description", [](const Config& c) { return c.config->description; })
      .def_property_readonly("model_name",
                             [](const Config& c) { return c.config->tracker.model->name; })
      .def_property_readonly(
          "marker_names",
          [](const Config& c) {
            return names_of(c.config->tracker.markers, &MarkerTarget::marker);
          },
          "Tracked markers, in the order Tracker.track takes an array")
      .def_property_readonly(
          "joint_names",
          [](const Config& c) { return names_of(c.config->tracker.model->joints, &Joint::name); })
      .def_property_readonly("segment_names",
                             [](const Config& c) {
                               return names_of(c.config->tracker.model->segments, &Segment::name);
                             })
      .def_property_readonly("angle_names",
                             [](const Config& c) {
                               return coordinate_names(*c.config->tracker.model,
                                                       CoordinateKind::rotation);
                             })
      .def_property_readonly("translation_names",
                             [](const Config& c) {
                               return coordinate_names(*c.config->tracker.model,
                                                       CoordinateKind::translation);
                             })
      .def_property_readonly(
          "json", [](const Config& c) { return c.json; },
          "The config's JSON text (fabrikd-config/1) as it was loaded")
      .def(py::pickle(&config_state, &config_from_state))
      .def_property_readonly(
          "calibration_report", [](const Config& c) { return c.report; },
          "calibrate(): the summary `fabrik calibrate` prints, else ''")
      .def("__repr__", [](const Config& c) {
        return "<fabrik.Config " + c.config->file + ": model '" + c.config->tracker.model->name +
               "', " + std::to_string(c.config->tracker.markers.size()) + " markers>";
      });
  m.def("load_config", &load, py::arg("path") = py::none(),
        "A daemon config (fabrikd-config/1 JSON) from `path`, or a model (fabrikd-model/1) "
        "tracked with the default config's settings; no path: the embedded default config "
        "(the built-in full-body model). Raises FileNotFoundError, or ConfigError (a "
        "ValueError) naming the file, the JSON pointer and the fix.");
  m.def("calibrate", &calibrate, py::arg("template"), py::arg("static"),
        py::arg("output") = py::none(), py::kw_only(), py::arg("first_frame") = -1,
        py::arg("frames") = -1, py::arg("auto_window") = -1, py::arg("lab_up") = "",
        py::arg("lab_forward") = "", py::arg("keep_zeros") = false,
        "A subject's config from a model template (fabrikd-template/1) and a static trial "
        "(.trc/.c3d), the same code as `fabrik calibrate`; written to `output` when given. "
        "first_frame (the file's frame number) and frames choose the averaging window, "
        "auto_window the stillest window of that many frames. Marker templates only: a "
        "keypoint template is a CalibrationError (use `fabrik calibrate --trial`); a template's "
        "orientation sensors are left out, said in calibration_report and as a UserWarning. "
        "Releases the GIL. Raises "
        "FileNotFoundError, ConfigError, FormatError (ValueErrors), CalibrationError "
        "(a RuntimeError), or OSError when `output` cannot be written.");
}

}  // namespace fabrik::python
