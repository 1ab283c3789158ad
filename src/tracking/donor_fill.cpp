#include "donor_fill.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "triad.hpp"

namespace fabrik {

namespace {

struct Triple {
  int a, b, c;  // a < 0: the frame candidate
  double score_m;
};

}  // namespace

bool fill_from_donors(std::size_t frames, std::size_t n, std::span<const double> times_s,
                      std::span<const Eigen::Vector3d> markers_m,
                      std::span<const std::uint8_t> visible, int marker, std::size_t first,
                      std::size_t end, const DonorFillSettings& settings,
                      std::span<Eigen::Vector3d> out, const FrameCandidate* skeleton,
                      double* donor_share, std::span<const std::uint8_t> allowed) {
  const auto i = static_cast<std::size_t>(marker);
  if (end <= first || end > frames || i >= n || out.size() != end - first) return false;
  const auto seen = [&](std::size_t f, std::size_t m) { return visible[f * n + m] != 0; };
  // A side is one where the marker is measured next to the gap: a gap clipped to the frames
  // in which any marker is seen (two_sided_fill) has no side at its clipped edge.
  const bool before = first > 0 && seen(first - 1, i), after = end < frames && seen(end, i);
  if (!before && !after) return false;
  const std::size_t lo = before ? first - 1 : first, hi = after ? end : end - 1;  // [lo, hi]
  const auto at = [&](std::size_t f, std::size_t m) -> const Eigen::Vector3d& {
    return markers_m[f * n + m];
  };

  // Frames near the gap that the choice is made on.
  const std::size_t len = end - first;
  const double span_s = std::max(settings.context_s,
                                 settings.context_gaps * (times_s[hi] - times_s[lo]));
  std::size_t c_lo = lo, c_hi = hi;
  while (c_lo > 0 && times_s[lo] - times_s[c_lo - 1] <= span_s) --c_lo;
  while (c_hi + 1 < frames && times_s[c_hi + 1] - times_s[hi] <= span_s) ++c_hi;

  // Donors: measured throughout the gap and on its measured sides; ranked by
  // the spread of their distance to the marker where both were measured.
  struct Ranked {
    int m;
    double spread_m;
  };
  std::vector<Ranked> ranked;
  for (std::size_t m = 0; m < n; ++m) {
    if (m == i || (!allowed.empty() && !allowed[m])) continue;
    bool ok = true;
    for (std::size_t f = lo; f <= hi && ok; ++f) ok = seen(f, m);
    if (!ok) continue;
    DistanceSpread spread;
    for (std::size_t f = c_lo; f <= c_hi; ++f)
      if (seen(f, i) && seen(f, m)) spread.add((at(f, m) - at(f, i)).norm());
    if (spread.frames < 3) continue;
    ranked.push_back({static_cast<int>(m), spread.spread_m()});
  }
  std::sort(ranked.begin(), ranked.end(),
            [](const Ranked& x, const Ranked& y) { return x.spread_m < y.spread_m; });
  if (ranked.size() > static_cast<std::size_t>(settings.candidates))
    ranked.resize(static_cast<std::size_t>(settings.candidates));
  if (ranked.size() < 3 && !skeleton) return false;

  // The marker's coordinates in a candidate's frame, per context frame
  // (unusable where any of the four is missing or the triangle is flat).
  const std::size_t width = c_hi - c_lo + 1;
  std::vector<Eigen::Vector3d> local(width);
  std::vector<std::uint8_t> usable(width);
  std::vector<std::size_t> run(width);
  // The fill of positions [s, e) (context indices) from the sides that exist.
  const auto interpolate = [&](std::size_t s, std::size_t e, std::size_t k) -> Eigen::Vector3d {
    if (!before) return local[e];
    if (!after) return local[s - 1];
    const double w = static_cast<double>(k - s + 1) / static_cast<double>(e - s + 1);
    return (1.0 - w) * local[s - 1] + w * local[e];
  };
  // Simulated gaps of the real one's length (shorter where the measured runs
  // are), each with the sides the real one has: the RMS error, or NaN.
  const auto cross_validate = [&]() {
    std::size_t longest = 0;
    for (std::size_t k = 0; k < width; ++k) {
      run[k] = usable[k] ? (k > 0 ? run[k - 1] : 0) + 1 : 0;
      longest = std::max(longest, run[k]);
    }
    const std::size_t sides = (before ? 1 : 0) + (after ? 1 : 0);
    if (longest < sides + 1) return static_cast<double>(NAN);
    const std::size_t l = std::min(len, longest - sides);
    const std::size_t stride = std::max<std::size_t>(1, l / 4);
    double sq = 0.0;
    std::size_t samples = 0;
    for (std::size_t s = before ? 1 : 0; s + l + (after ? 1 : 0) <= width;) {
      const std::size_t e = s + l;
      const std::size_t need_end = after ? e : e - 1;
      // Usable throughout [s - 1 or s, e or e - 1].
      if (run[need_end] < need_end - (before ? s - 1 : s) + 1) {
        ++s;
        continue;
      }
      for (std::size_t k = s; k < e; ++k) sq += (interpolate(s, e, k) - local[k]).squaredNorm();
      samples += l;
      s += stride;
    }
    return samples ? std::sqrt(sq / static_cast<double>(samples)) : static_cast<double>(NAN);
  };

  std::vector<Triple> scored;
  if (skeleton) {
    for (std::size_t f = c_lo; f <= c_hi; ++f) {
      const std::size_t k = f - c_lo;
      usable[k] = seen(f, i) && skeleton->origin_m[f].allFinite();
      if (usable[k])
        local[k] = skeleton->q_world[f].conjugate() * (at(f, i) - skeleton->origin_m[f]);
    }
    const double score = cross_validate();
    if (std::isfinite(score)) scored.push_back({-1, -1, -1, score});
  }
  const int count = static_cast<int>(ranked.size());
  for (int x = 0; x < count; ++x)
    for (int y = x + 1; y < count; ++y)
      for (int z = y + 1; z < count; ++z) {
        const int a = ranked[x].m, b = ranked[y].m, c = ranked[z].m;
        Eigen::Matrix3d r;
        bool spans = true;
        for (std::size_t f = lo; f <= hi && spans; ++f)
          spans = triad(at(f, a), at(f, b), at(f, c), settings.min_sine, r);
        if (!spans) continue;
        for (std::size_t f = c_lo; f <= c_hi; ++f) {
          const std::size_t k = f - c_lo;
          usable[k] = seen(f, i) && seen(f, a) && seen(f, b) && seen(f, c) &&
                      triad(at(f, a), at(f, b), at(f, c), settings.min_sine, r);
          if (usable[k]) local[k] = r.transpose() * (at(f, i) - at(f, a));
        }
        const double score = cross_validate();
        if (std::isfinite(score)) scored.push_back({a, b, c, score});
      }
  if (scored.empty()) return false;
  std::sort(scored.begin(), scored.end(),
            [](const Triple& x, const Triple& y) { return x.score_m < y.score_m; });
  if (!skeleton && !(scored.front().score_m <= settings.max_score_m)) return false;
  const std::size_t keep = std::min(scored.size(), static_cast<std::size_t>(settings.triples));

  std::fill(out.begin(), out.end(), Eigen::Vector3d::Zero());
  double weight_sum = 0.0, donor_weight = 0.0;
  for (std::size_t t = 0; t < keep; ++t) {
    const Triple& tr = scored[t];
    const double w = 1.0 / std::pow(std::max(tr.score_m, settings.score_floor_m), 2);
    weight_sum += w;
    if (tr.a < 0) {
      for (std::size_t f = first; f < end; ++f) out[f - first] += w * skeleton->fill_m[f - first];
      continue;
    }
    donor_weight += w;
    Eigen::Matrix3d r;
    Eigen::Vector3d local_before = Eigen::Vector3d::Zero(), local_after = Eigen::Vector3d::Zero();
    if (before) {
      triad(at(lo, tr.a), at(lo, tr.b), at(lo, tr.c), 0.0, r);
      local_before = r.transpose() * (at(lo, i) - at(lo, tr.a));
    }
    if (after) {
      triad(at(hi, tr.a), at(hi, tr.b), at(hi, tr.c), 0.0, r);
      local_after = r.transpose() * (at(hi, i) - at(hi, tr.a));
    }
    for (std::size_t f = first; f < end; ++f) {
      const double u = static_cast<double>(f - first + 1) / static_cast<double>(len + 1);
      const Eigen::Vector3d l = !before ? local_after
                                : !after ? local_before
                                         : ((1.0 - u) * local_before + u * local_after).eval();
      triad(at(f, tr.a), at(f, tr.b), at(f, tr.c), 0.0, r);
      out[f - first] += w * (at(f, tr.a) + r * l);
    }
  }
  for (Eigen::Vector3d& p : out) p /= weight_sum;
  if (donor_share) *donor_share = donor_weight / weight_sum;
  return true;
}

}  // namespace fabrik
