#pragma once
// Angle unit factors, one owner for the whole project (internal: not installed).

#include <numbers>

namespace fabrik {

inline constexpr double kDegPerRad = 180.0 / std::numbers::pi;
inline constexpr double kRadPerDeg = std::numbers::pi / 180.0;

}  // namespace fabrik
