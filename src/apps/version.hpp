#pragma once
#include <string_view>
namespace fabrik {
inline constexpr std::string_view kVersion = "0.1.0";
}
