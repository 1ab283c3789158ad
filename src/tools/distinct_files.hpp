// Refuses, before any work, a command whose outputs cannot be written as asked: an output that
// would overwrite one of its inputs or another output (`fabrik solve --input walk.trc --output
// walk.trc` replaced the trial it read), two outputs one stream would take (a terminal, a
// pipe), or an output that names a folder that does not exist.
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace fabrik::tools {

struct NamedFile {
  std::string option;  // "--output", or "--markers (its .filled.csv)"
  std::string path;    // empty: not given, skipped
  bool output = true;  // inputs may share a file (a static trial as the trial); outputs may not
};

// Throws std::invalid_argument naming both options when an output's path is the same file as
// another given path (the same after symlinks, links to nothing included, `.` and `..`; or a
// hard link of it). /dev/null and /dev/ptmx may be named by any number; another device (a
// terminal, a disk), a pipe or a socket by one output only, and by inputs (/dev/tty,
// /dev/console and /dev/tty0 are the terminal they stand for). Not
// caught: two new names that differ in case only, on a case-insensitive filesystem.
void require_distinct_files(const std::vector<NamedFile>& files);

// Throws std::invalid_argument naming the option when an output's path is a folder, its
// folder does not exist or is not one, or the file cannot be written there (an existing file
// opened to append, a new one's folder by making a file of its own, unnamed where the system
// can): found at once, not after a solve of minutes.
void require_output_folders(const std::vector<NamedFile>& files);

// Both, folders first: `sub/../x` with no `sub` is named for its missing folder, not as the
// same file as `x` (the system could not open it).
void require_usable_outputs(const std::vector<NamedFile>& files);

namespace detail {
// A device number as the kernel encodes it for user space (new_encode_dev: minor's low 8 bits,
// then 12 bits of major, then minor's upper 12), as TIOCGDEV gives it.
dev_t device_from_kernel(unsigned int encoded);

// The console /dev/console writes to: the last name of /sys/class/tty/console/active ("tty0
// ttyS0" gives "ttyS0"), or "" where there is none.
std::string console_behind(std::string_view active);

// A device number as sysfs spells it ("4:64\n"), or nothing where the text is not one.
std::optional<dev_t> device_from_sysfs(std::string_view text);

// A device's number as outputs are compared by: /dev/tty's the controlling terminal's,
// /dev/console's and /dev/tty0's the terminal they stand for (read from sysfs); 0 where
// `path` does not exist.
dev_t device_number(const std::string& path);

// Why no file can be made in `folder`, or "": an unnamed file where the system can make one;
// else (or with `unnamed_first` false, as a test asks) a named one, removed at once.
std::string cannot_make_file_in(const std::filesystem::path& folder, bool unnamed_first = true);
}  // namespace detail

}  // namespace fabrik::tools
