#include "info_command.hpp"

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>

#include "common/format_number.hpp"
#include "common/safe_text.hpp"
#include "tools/run_command.hpp"

namespace fabrik::apps {

namespace {

const auto& fmt = format_number;

std::string join(const std::vector<std::string>& names, std::size_t at_most) {
  std::string out;
  for (std::size_t i = 0; i < names.size() && i < at_most; ++i) out += (i ? ", " : "") + names[i];
  if (names.size() > at_most) out += ", ...";
  return out;
}

std::string table_format(const io::RecordingInfo& info) {
  return "OpenSim table (" + std::filesystem::path(info.path).extension().string() + ")";
}

}  // namespace

nlohmann::json info_json(const io::RecordingInfo& info) {
  nlohmann::json j = {{"file", info.path}, {"kind", info.kind}};
  if (info.table) {
    const io::OpenSimTable& t = *info.table;
    nlohmann::json header = nlohmann::json::object();
    for (const auto& [key, value] : t.header) header[key] = value;
    j["format"] = table_format(info);
    j["name"] = t.name;
    j["header"] = header;
    j["columns"] = t.columns;
    j["rows"] = t.rows;
    j["time_s"] = {t.first_time_s, t.last_time_s};
    j["rate_hz"] = t.rate_hz;
    j["rate_source"] = t.rate_source;
    j["cells"] = t.cell_kind;
    j["warnings"] = t.warnings;
    return j;
  }
  const io::MarkerTrial& t = info.trial;
  const io::RecordingFacts& f = t.source;
  nlohmann::json markers = nlohmann::json::array();
  for (const io::MarkerSamples& m : info.markers) {
    markers.push_back({{"label", m.label},
                       {"missing", m.missing},
                       {"zeros", m.zeros},
                       {"longest_gap", m.longest_gap}});
  }
  j["format"] = f.format;
  j["number_format"] = f.number_format;
  j["rate_hz"] = t.rate_hz;
  j["units"] = f.units;
  j["frames"] = f.frames;
  j["first_frame"] = t.first_frame;
  j["last_frame"] = static_cast<long long>(t.first_frame) + static_cast<long long>(f.frames) - 1;
  j["markers"] = markers;
  j["analog"] = {{"channels", f.analog_channels},
                 {"rate_hz", f.analog_rate_hz},
                 {"labels", f.analog_labels}};
  j["rotations"] = {{"count", f.rotations}, {"labels", f.rotation_labels}};
  nlohmann::json repeated = nlohmann::json::array();
  for (const io::RepeatedLabel& r : f.repeated_labels)
    repeated.push_back({{"label", r.label}, {"first", r.first}, {"second", r.second}});
  j["repeated_labels"] = repeated;
  if (f.format == "TRC") {
    const auto steps = [](const io::TimeSteps& s) {
      nlohmann::json out = {{"rows", s.rows}};
      if (s.rows > 0)
        out.update({{"first_frame", s.first_frame},
                    {"first_line", s.first_line},
                    {"time_s", s.time_s},
                    {"previous_s", s.previous_s}});
      return out;
    };
    j["time_column"] = {{"backwards", steps(f.time_backwards)},
                        {"standing", steps(f.time_standing)}};
  }
  j["warnings"] = t.warnings;
  return j;
}

std::string info_text(const io::RecordingInfo& info) {
  std::string out = "file        " + info.path + "\n";
  const auto line = [&](const char* key, const std::string& value) {
    out += std::string(key) + std::string(12 - std::string(key).size(), ' ') + value + "\n";
  };
  const auto warnings = [&](const std::vector<std::string>& ws) {
    if (ws.empty()) line("warnings", "none");
    for (const std::string& w : ws) line("warning", w);
  };
  if (info.table) {
    const io::OpenSimTable& t = *info.table;
    line("format", table_format(info) + (t.name.empty() ? "" : " '" + t.name + "'") +
                       ": no markers (fabrik tracks " + ".trc and .c3d marker files)");
    std::vector<std::string> header;
    for (const auto& [key, value] : t.header) header.push_back(key + "=" + value);
    line("header", header.empty() ? "no key=value lines" : join(header, 12));
    line("columns", std::to_string(t.columns.size()) + ": " + join(t.columns, 12));
    line("rows", std::to_string(t.rows) + ", time " + fmt("%g", t.first_time_s) + " to " +
                     fmt("%g", t.last_time_s) + " s");
    line("rate", t.rate_hz > 0.0 ? fmt("%g Hz", t.rate_hz) + " (" + t.rate_source + ")"
                                 : "unknown");
    line("cells", t.cell_kind);
    warnings(t.warnings);
    return out;
  }
  const io::MarkerTrial& t = info.trial;
  const io::RecordingFacts& f = t.source;
  line("format", f.format + " (" + f.number_format + ")");
  line("rate", t.rate_hz > 0.0 ? fmt("%g Hz", t.rate_hz) : "none");
  line("units", f.units + " (converted to metres when read)");
  const long long last = static_cast<long long>(t.first_frame) + static_cast<long long>(f.frames) - 1;
  line("frames", std::to_string(f.frames) +
                     (f.frames > 0 ? " (" + std::to_string(t.first_frame) + " to " +
                                         std::to_string(last) + ")"
                                   : "") +
                     (t.rate_hz > 0.0 ? fmt(", %.2f s", static_cast<double>(f.frames) / t.rate_hz)
                                      : ""));
  std::size_t missing = 0, zeros = 0, gappy = 0;
  for (const io::MarkerSamples& m : info.markers) {
    missing += m.missing;
    zeros += m.zeros;
    gappy += m.missing > 0 ? 1 : 0;
  }
  std::string markers = std::to_string(t.markers());
  if (t.markers() == 0) {
    markers = "none: no 3D marker data";
  } else if (missing == 0) {
    markers += ", no missing samples";
  } else {
    markers += "; " + std::to_string(missing) + " missing samples in " + std::to_string(gappy) +
               " of them (" + std::to_string(zeros) + " exact (0, 0, 0), read as missing)";
  }
  line("markers", markers);
  if (!info.markers.empty()) {
    std::size_t width = 6;
    for (const io::MarkerSamples& m : info.markers) width = std::max(width, m.label.size());
    char row[512];
    std::snprintf(row, sizeof row, "  %-*s %8s %7s %12s\n", static_cast<int>(width), "marker",
                  "missing", "zeros", "longest gap");
    out += row;
    for (const io::MarkerSamples& m : info.markers) {
      std::snprintf(row, sizeof row, "  %-*s %8zu %7zu %12zu\n", static_cast<int>(width),
                    m.label.c_str(), m.missing, m.zeros, m.longest_gap);
      out += row;
    }
  }
  line("analog", f.analog_channels == 0
                     ? "none"
                     : std::to_string(f.analog_channels) + " channels" +
                           (f.analog_rate_hz > 0.0 ? fmt(" at %g Hz", f.analog_rate_hz) : "") +
                           " (not read)" +
                           (f.analog_labels.empty() ? "" : ": " + join(f.analog_labels, 8)));
  line("rotations", f.rotations == 0 ? "none"
                                     : std::to_string(f.rotations) + " (not read)" +
                                           (f.rotation_labels.empty()
                                                ? ""
                                                : ": " + join(f.rotation_labels, 8)));
  warnings(t.warnings);
  return out;
}

void add_info_command(CLI::App& app) {
  struct Args {
    std::vector<std::string> files;
    bool json = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "info", std::string("What a recording holds: format, rate, units, frames, markers with ") +
                  "missing samples and exact zeros, analog channels, rotations. Reads " +
                  io::kInfoFormats);
  cmd->add_option("files", a->files, "Recordings")->required();
  cmd->add_flag("--json", a->json, "One JSON object per file (an array for several)");
  cmd->callback([a] {
    tools::run_command("info", [&] {
      nlohmann::json all = nlohmann::json::array();
      std::size_t failed = 0;
      for (const std::string& file : a->files) {
        try {
          const io::RecordingInfo info = io::inspect_recording(file);
          if (a->json) {
            all.push_back(info_json(info));
          } else {
            std::cout << (&file == &a->files.front() ? "" : "\n") << info_text(info);
          }
        } catch (const std::exception& e) {
          std::fprintf(stderr, "fabrik info: %s\n", safe_lines(e.what()).c_str());
          ++failed;
        }
      }
      if (a->json) std::cout << (a->files.size() == 1 && !all.empty() ? all[0] : all).dump(2) << "\n";
      std::cout.flush();
      if (failed > 0) {
        throw std::runtime_error(std::to_string(failed) + " of " +
                                 std::to_string(a->files.size()) + " files could not be read");
      }
    });
  });
}

}  // namespace fabrik::apps
