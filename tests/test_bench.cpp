// The benchmarks' own checks: the paper experiment's postures (free joints and
// with range-of-motion limits) and the full-body run with limits on and off.
#include <catch2/catch.hpp>

#include <fstream>

#include "bench/bench.hpp"
#include "temp_file.hpp"

using namespace fabrik;

TEST_CASE("The paper experiment passes its posture checks, also with joint limits", "[bench]") {
  bench::PaperOptions o;
  o.repeats = 3;  // the checks, not the times
  const nlohmann::json r = bench::run_paper(o);
  for (const auto& [name, c] : r["checks"].items()) {
    CAPTURE(name, c.dump());
    CHECK(c["pass"].get<bool>());
  }
  REQUIRE(r.contains("with_limits"));
  for (const auto& [name, c] : r["with_limits"]["checks"].items()) {
    CAPTURE(name, c.dump());
    CHECK(c["pass"].get<bool>());
  }
  // The limits change the answer: the elbows may not hyperextend, so both
  // wrists end further than without limits.
  const auto& free = r["algorithms"]["fabrik"]["error_mm"];
  const auto& limited = r["with_limits"]["algorithms"]["fabrik"]["error_mm"];
  CHECK(limited["r_wrist"].get<double>() > free["r_wrist"].get<double>() + 1.0);
  CHECK(r["all_checks_pass"].get<bool>());
}

TEST_CASE("The full-body benchmark tracks a model with limits with and without them", "[bench]") {
  // The built-in full-body model with its knees as hinges.
  std::ifstream in(std::string(FABRIK_SOURCE_DIR) + "/config/models/fullbody.json");
  nlohmann::json model = nlohmann::json::parse(in);
  for (auto& s : model["segments"])
    if (s["name"] == "r_shank" || s["name"] == "l_shank")
      s["joint"] = {{"type", "hinge"}, {"range_deg", {{"z", {-140, 5}}}}};
  test::TempFile file(".json");
  std::ofstream(file.path()) << model.dump();
  bench::FullbodyOptions o;
  o.frames = 50;
  o.model = file.path();
  const nlohmann::json r = bench::run_fullbody(o);
  REQUIRE(r["model"]["joint_limits"].get<bool>());
  REQUIRE(r.contains("without_limits"));
  CHECK(r["iterations_mean"].get<double>() > 0.0);
  CHECK(r["without_limits"]["iterations_mean"].get<double>() > 0.0);
}
