// LinkStep's known answers: a step puts the moving end at the link's length
// on the line towards the target, and a chained step (which derives its
// distance from the previous step's numbers) lands where the direct step
// from the previous end lands, on runs that stretch and runs that fold.
#include <catch2/catch.hpp>

#include <random>

#include "solver/link_step.hpp"

using fabrik::LinkStep;

TEST_CASE("A link step puts the end at the link's length towards the target", "[solver][link_step]") {
  LinkStep s;
  Eigen::Vector3d end_m;
  REQUIRE(s.step({1, 2, 3}, {1, 2, 7}, 0.5, false, end_m));
  CHECK((end_m - Eigen::Vector3d(1, 2, 3.5)).norm() < 1e-15);
  // A target on the fixed end gives no direction: refused, end untouched.
  end_m = {9, 9, 9};
  CHECK_FALSE(s.step({1, 1, 1}, {1, 1, 1}, 0.5, false, end_m));
  CHECK(end_m == Eigen::Vector3d(9, 9, 9));
}

TEST_CASE("A chained link step lands where the direct step from the previous end lands", "[solver][link_step]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coord(-1.0, 1.0), length(0.01, 0.5);
  const double fold = GENERATE(1.0, 0.05);  // targets spread out, or bunched (a folding run)
  double worst_m = 0;
  for (int run = 0; run < 200; ++run) {
    LinkStep chained, direct;
    Eigen::Vector3d from_m(coord(rng), coord(rng), coord(rng));
    Eigen::Vector3d end_chained = Eigen::Vector3d::Zero(), end_direct = Eigen::Vector3d::Zero();
    bool have = false;
    for (int k = 0; k < 50; ++k) {
      const Eigen::Vector3d to_m = from_m + fold * Eigen::Vector3d(coord(rng), coord(rng), coord(rng));
      const double len_m = length(rng);
      const bool ok_direct = direct.step(from_m, to_m, len_m, false, end_direct);
      const bool ok_chained = chained.step(from_m, to_m, len_m, have, end_chained);
      REQUIRE(ok_direct == ok_chained);
      if (!ok_direct) break;
      worst_m = std::max(worst_m, (end_chained - end_direct).norm());
      // Both start the next step from the chained end: each step's error is its own (a
      // step from a start near a close target magnifies a difference in the start, so
      // two runs that drift apart by a rounding would diverge for no fault of the step).
      from_m = end_chained;
      have = true;
    }
  }
  INFO("fold " << fold);
  CHECK(worst_m < 1e-12);
}
