#include "paper_experiment.hpp"

#include <filesystem>
#include <numbers>

#include "config/json_reader.hpp"
#include "config/model_loader.hpp"
#include "config/resources.hpp"
#include "config/solver_options_json.hpp"
#include "solver/joint_angles.hpp"
#include "stats.hpp"

namespace fabrik::bench {

using nlohmann::json;

namespace {

std::shared_ptr<const Model> read_model(const std::string& experiment_path,
                                        const std::string& relative) {
  // The model path is relative to the experiment file (or embedded).
  const std::filesystem::path dir = std::filesystem::path(experiment_path).parent_path();
  const std::string path =
      std::filesystem::exists(experiment_path) ? (dir / relative).string() : relative;
  return std::make_shared<const Model>(
      load_model(JsonReader::parse(read_config_text(path), path), path));
}

json posture_json(const Model& m, const Posture& p) {
  json joints = json::object();
  for (const Joint& j : m.joints) {
    const Eigen::Vector3d x = p.point_world_m(m, j.point);
    joints[j.name] = {x.x(), x.y(), x.z()};
  }
  for (const Point& pt : m.points)
    if (pt.kind == PointKind::end_site) {
      const Eigen::Vector3d x = p.segments[pt.segment].to_world(pt.p_local_m);
      joints[pt.name] = {x.x(), x.y(), x.z()};
    }
  json segments = json::array();  // each segment as its list of point names, base first
  json angles = json::object();   // limited joints: Cardan z, x, y in degrees
  for (int s = 0; s < static_cast<int>(m.segments.size()); ++s) {
    const Segment& seg = m.segments[s];
    json names = json::array();
    for (int k = seg.first_point; k < seg.first_point + seg.point_count; ++k)
      names.push_back(m.points[k].name);
    segments.push_back({{"name", seg.name}, {"points", names}});
    if (seg.joint.limited()) {
      const Eigen::Vector3d a = joint_angles_rad(m, p, s) * (180.0 / std::numbers::pi);
      angles[seg.name] = {{"z", a[0]}, {"x", a[1]}, {"y", a[2]}};
    }
  }
  json out = {{"points_m", joints}, {"segments", segments}};
  if (!angles.empty()) out["joint_angles_deg"] = angles;
  return out;
}

}  // namespace

Experiment load_experiment(const std::string& path) {
  const json doc = JsonReader::parse(read_config_text(path), path);
  const JsonReader root(doc, path);
  root.only_keys({"format", "description", "model", "limits_model", "units", "targets", "solver",
                  "repeats"});
  Experiment e;
  e.model = read_model(path, root.at("model").as_string());
  if (root.has("limits_model")) {
    e.limits_model = read_model(path, root.at("limits_model").as_string());
    if (e.limits_model->points.size() != e.model->points.size())
      root.at("limits_model")
          .fail("the limits model is not the same body as the model",
                "give it the same segments and points, with joints added");
  }
  const double scale = metres_per_unit(root.at("units"));
  const JsonReader targets = root.at("targets");
  targets.expect_array();
  for (std::size_t i = 0; i < targets.value().size(); ++i) {
    const JsonReader t = targets.at(i);
    t.only_keys({"point", "position", "level", "weight"});
    const std::string name = t.at("point").as_string();
    const int point = e.model->find_point(name);
    if (point < 0) t.at("point").fail("no point '" + name + "' in the model", "name a model point");
    e.targets.push_back({point, static_cast<int>(t.get("level", 0LL, -1000LL, 1000LL)),
                         t.get("weight", 1.0, 1e-6, 1e6)});
    e.target_names.push_back(name);
    e.positions_m.push_back(t.at("position").as_vec3() * scale);
  }
  e.solver = read_solver_options(root.at("solver"));
  e.repeats = static_cast<int>(root.get("repeats", 1000LL, 1LL, 10000000LL));
  return e;
}

double Run::median_us() const {
  return quantile(times_us, 0.5);
}

json run_json(const Experiment& e, const Model& model, const Run& run) {
  json errors = json::object();
  for (std::size_t i = 0; i < e.targets.size(); ++i)
    errors[e.target_names[i]] = run.distances_m[i] * 1e3;
  return {{"median_us", run.median_us()},
          {"p99_us", quantile(run.times_us, 0.99)},
          {"runs", run.times_us.size()},
          {"status", to_string(run.result.status)},
          {"iterations", run.result.iterations},
          {"passes", run.result.passes},
          {"error_mm", errors},
          {"posture", posture_json(model, run.posture)}};
}

}  // namespace fabrik::bench
