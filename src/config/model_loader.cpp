#include "model_loader.hpp"

#include "json_reader.hpp"
#include "solver/model_builder.hpp"

namespace fabrik {

double metres_per_unit(const JsonReader& units) {
  const std::string u = units.as_string();
  if (u == "m") return 1.0;
  if (u == "mm") return 1e-3;
  units.fail("unknown unit '" + u + "'", "use \"m\" or \"mm\"");
}

namespace {
void read_points(const JsonReader& obj, double scale, bool marker, std::vector<PointSpec>& out) {
  obj.expect_object();
  for (auto it = obj.value().begin(); it != obj.value().end(); ++it) {
    const JsonReader p = obj.at(it.key());
    out.push_back(PointSpec{it.key(), p.as_vec3() * scale, marker});
  }
}
}  // namespace

Model load_model(const nlohmann::json& doc, const std::string& file) {
  return load_model(JsonReader(doc, file));
}

Model load_model(const JsonReader& root) {
  root.only_keys({"format", "name", "units", "root_position", "segments", "description"});
  if (root.has("format") && root.at("format").as_string() != "fabrikd-model/1")
    root.at("format").fail("unsupported format '" + root.at("format").as_string() + "'",
                           "use \"fabrikd-model/1\"");
  const std::string name = root.get("name", std::string("model"));
  const double scale = metres_per_unit(root.at("units"));
  const Eigen::Vector3d root_m = root.has("root_position")
                                     ? Eigen::Vector3d(root.at("root_position").as_vec3() * scale)
                                     : Eigen::Vector3d::Zero();
  const JsonReader segs = root.at("segments");
  segs.expect_array();
  std::vector<SegmentSpec> specs;
  for (std::size_t i = 0; i < segs.value().size(); ++i) {
    const JsonReader s = segs.at(i);
    s.only_keys({"name", "parent", "base", "points", "markers", "description"});
    SegmentSpec spec;
    spec.name = s.at("name").as_string();
    spec.parent =
        s.has("parent") && !s.at("parent").value().is_null() ? s.at("parent").as_string() : "";
    spec.base = s.at("base").as_string();
    if (s.has("points")) read_points(s.at("points"), scale, false, spec.points);
    if (s.has("markers")) read_points(s.at("markers"), scale, true, spec.points);
    specs.push_back(std::move(spec));
  }
  try {
    return build_model(name, specs, root_m);
  } catch (const ModelError& e) {
    // Point the message at the field the builder complained about.
    std::string pointer = root.pointer() + "/segments";
    if (e.segment() >= 0) {
      pointer += "/" + std::to_string(e.segment());
      const SegmentSpec& spec = specs[e.segment()];
      if (e.point() >= 0) {
        const PointSpec& ps = spec.points[e.point()];
        pointer += std::string(ps.marker ? "/markers/" : "/points/") + json_pointer_token(ps.name);
      } else {
        pointer += "/" + e.field();
      }
    } else if (e.field() != "segments") {
      pointer = root.pointer() + "/" + e.field();
    }
    throw ConfigError(root.file(), pointer, e.what(), "see the model format in README.md");
  }
}

Model load_model_file(const std::string& path) {
  return load_model(JsonReader::parse_file(path), path);
}

}  // namespace fabrik
