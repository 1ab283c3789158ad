// Order statistics of timing samples (shared with the tools and evaluations).
#pragma once

#include "common/quantile.hpp"

namespace fabrik::bench {
using fabrik::mean;
using fabrik::quantile;
}  // namespace fabrik::bench
