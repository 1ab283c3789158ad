// Helpers shared by the TRC and C3D code; not part of the public API.
#pragma once

#include <fstream>
#include <istream>
#include <optional>
#include <string>
#include <string_view>

#include "io/marker_trial.hpp"

namespace fabrik::io::detail {

// Opens `path` for binary reading; FormatError if it is missing, not a file or unreadable.
std::ifstream open_input(const std::string& path);
// Checks what both writers need: a positive rate and positions_m sized frames x markers
// (std::invalid_argument otherwise). Returns the metres -> file units factor for "mm" or "m".
double check_trial_for_writing(const MarkerTrial& trial, const std::string& units,
                               const char* writer);

std::string_view trim(std::string_view s);

// Reads the next line into `line` without its line ending (LF or CRLF), storing at most
// `max_bytes` of it: a line costs no more than that, whatever the file holds. `unterminated`:
// the file's last line, which has no line ending (a file cut short may end so).
enum class LineRead { line, unterminated, end, too_long };
LineRead read_line(std::istream& in, std::string& line, std::size_t max_bytes);

// Metres per file unit for "mm", "cm" or "m" in any case (and their long names); none otherwise.
std::optional<double> metres_per_unit(std::string_view units);

// Finds labels on more than one marker (trial.source.repeated_labels). With
// options.refuse_ambiguous that is a FormatError: "<where>: marker 'X' labels <numbering> a
// and b ..." ("columns", numbered as number(m) gives them); otherwise a warning each.
void check_repeated_labels(MarkerTrial& trial, const std::string& path, const ReadOptions& options,
                           const std::string& where, const std::string& numbering,
                           std::size_t (*number)(std::size_t), const std::string& fix);

// Adds one warning to `trial` when some of its samples were exactly (0, 0, 0)
// (trial.source.zero_samples), saying which markers and how they were read.
void warn_about_zeros(MarkerTrial& trial, const ReadOptions& options);

// Sets trial.source.typical_span_m. Adds one warning to `trial` when its markers span less than
// 20 mm or more than 100 m in a typical frame: a body spans about a metre, so the file's unit
// (`unit_field`, where it is written) is most likely wrong, e.g. metres labelled mm. Where the
// spread is past the bounds the commands refuse, the warning is also trial.source.unit_problem.
void warn_about_units(MarkerTrial& trial, const std::string& unit_field);

}  // namespace fabrik::io::detail
