// `fabrik info FILE...`: what a recording holds (format, rate, units, frames, markers with
// their missing samples and exact zeros, analog channels, rotations; OpenSim tables' columns
// and rows), as text or, with --json, for scripts.
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>

#include "io/recording_info.hpp"

namespace fabrik::apps {

nlohmann::json info_json(const io::RecordingInfo& info);
std::string info_text(const io::RecordingInfo& info);

void add_info_command(CLI::App& app);

}  // namespace fabrik::apps
