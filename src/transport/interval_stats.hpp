// Samples over one stats interval (solve time, queue latency) with their
// quantiles. Capacity is reserved up front; past it, samples are counted but
// not kept, so a flood cannot grow memory.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace fabrik::wire {

class IntervalSamples {
 public:
  explicit IntervalSamples(std::size_t capacity = 1 << 16) { samples_.reserve(capacity); }
  void add(double v) {
    if (samples_.size() < samples_.capacity()) samples_.push_back(v);
    max_ = std::max(max_, v);
  }
  // Nearest-rank quantile of what was kept, 0 when empty. Reorders samples.
  double quantile(double q) {
    if (samples_.empty()) return 0.0;
    const auto k = static_cast<std::size_t>(q * static_cast<double>(samples_.size() - 1) + 0.5);
    std::nth_element(samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(k),
                     samples_.end());
    return samples_[k];
  }
  double max() const { return max_; }
  std::size_t size() const { return samples_.size(); }
  void clear() {
    samples_.clear();
    max_ = 0.0;
  }

 private:
  std::vector<double> samples_;
  double max_ = 0.0;
};

}  // namespace fabrik::wire
