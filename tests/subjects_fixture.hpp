// Multi-subject configs for tests: subject config files (the embedded
// full-body model) in a temp directory, a daemon config listing them, and
// marker frames for several synthetic subjects spaced apart in the lab.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "config/daemon_config.hpp"
#include "synth/synthetic_motion.hpp"

namespace fabrik::test {

class SubjectsDir {
 public:
  SubjectsDir() {
    static std::mt19937_64 rng{std::random_device{}()};
    dir_ = std::filesystem::temp_directory_path() / ("fabrik_subjects_" + std::to_string(rng()));
    std::filesystem::create_directories(dir_);
  }
  ~SubjectsDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  SubjectsDir(const SubjectsDir&) = delete;
  SubjectsDir& operator=(const SubjectsDir&) = delete;

  // Writes NAME.json (one subject: the embedded full-body model) per name and
  // a daemon config listing them, with `extra` merged into its top level;
  // returns the daemon config's path.
  std::string write(const std::vector<std::string>& names,
                    const nlohmann::json& extra = nlohmann::json::object()) {
    nlohmann::json subjects = nlohmann::json::array();
    for (const std::string& name : names) {
      write_file(name + ".json",
                 nlohmann::json{{"format", "fabrikd-config/1"}, {"model", "models/fullbody.json"}});
      subjects.push_back({{"name", name}, {"config", name + ".json"}});
    }
    nlohmann::json config{{"format", "fabrikd-config/1"}, {"subjects", subjects}};
    config.update(extra);
    return write_file("daemon-" + std::to_string(++configs_) + ".json", config);
  }
  std::string write_file(const std::string& name, const nlohmann::json& content) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path) << content.dump(2);
    return path;
  }

 private:
  std::filesystem::path dir_;
  int configs_ = 0;
};

// Subject k's offset in the lab: 2 m apart along x, so that no two overlap.
inline Eigen::Vector3d subject_offset_m(int k) {
  return {2.0 * k, 0.0, 0.0};
}

// The markers of one subject of `setup` at time t_s of `motion`, in mm,
// shifted by `offset_m`, each name after `prefix` (e.g. "Alice:"), except `hidden`.
inline nlohmann::json subject_markers(const TrackerSetup& setup, SyntheticMotion& motion, double t_s,
                                      const Eigen::Vector3d& offset_m, const std::string& prefix,
                                      nlohmann::json into = nlohmann::json::object()) {
  const Model& m = *setup.model;
  Posture p = Posture::rest(m);
  motion.posture_at(t_s, p);
  for (const MarkerTarget& t : setup.markers) {
    const Eigen::Vector3d x = (p.point_world_m(m, t.point) + offset_m) * 1e3;
    into[prefix + t.marker] = {x.x(), x.y(), x.z()};
  }
  return into;
}

}  // namespace fabrik::test
