#include "distinct_files.hpp"

#include <fcntl.h>
#include <stdlib.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <stdexcept>

#include "common/device_path.hpp"

namespace fabrik::tools {

dev_t detail::device_from_kernel(unsigned int encoded) {
  return makedev((encoded & 0xfff00u) >> 8, (encoded & 0xffu) | ((encoded >> 12) & 0xfff00u));
}

std::string detail::console_behind(std::string_view active) {
  const auto end = active.find_last_not_of(" \t\n");
  if (end == std::string_view::npos) return {};
  const auto start = active.find_last_of(" \t\n", end);
  return std::string(active.substr(start == std::string_view::npos ? 0 : start + 1, end - start));
}

std::optional<dev_t> detail::device_from_sysfs(std::string_view text) {
  unsigned int major_number = 0, minor_number = 0;
  const char* const end = text.data() + text.size();
  auto [colon, e1] = std::from_chars(text.data(), end, major_number);
  if (e1 != std::errc() || colon == end || *colon != ':') return std::nullopt;
  auto [rest, e2] = std::from_chars(colon + 1, end, minor_number);
  if (e2 != std::errc() || (rest != end && *rest != '\n')) return std::nullopt;
  return makedev(major_number, minor_number);
}

namespace {

std::string first_line_of(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

// The terminal a console name stands for: /dev/console the kernel's console (the last of
// /sys/class/tty/console/active), /dev/tty0 the virtual console in front (tty0/active). Read
// from sysfs, never opened: opening a serial console and closing it could hang its line up.
std::optional<dev_t> console_device(dev_t rdev) {
  std::string name = rdev == makedev(5, 1)
                         ? detail::console_behind(first_line_of("/sys/class/tty/console/active"))
                         : "tty0";
  if (name == "tty0") name = detail::console_behind(first_line_of("/sys/class/tty/tty0/active"));
  if (name.empty() || name == "tty0" || name.find('.') != std::string::npos) return std::nullopt;
  std::replace(name.begin(), name.end(), '/', '!');  // sysfs's spelling of a '/' in a name
  return detail::device_from_sysfs(first_line_of("/sys/class/tty/" + name + "/dev"));
}

}  // namespace

// For /dev/tty, which stands for the process's controlling terminal, that terminal's
// (TIOCGDEV), where there is one. Only /dev/tty is opened: it is open already through the
// session, so this open and close hang up nothing.
dev_t detail::device_number(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return 0;
  if (!S_ISCHR(st.st_mode)) return st.st_rdev;  // a disk's numbers are its own
  if (st.st_rdev == makedev(5, 1) || st.st_rdev == makedev(4, 0))
    return console_device(st.st_rdev).value_or(st.st_rdev);
#ifdef TIOCGDEV
  if (st.st_rdev != makedev(5, 0)) return st.st_rdev;
  const int fd = ::open(path.c_str(), O_RDONLY | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return st.st_rdev;
  unsigned int encoded = 0;
  const bool told = ::ioctl(fd, TIOCGDEV, &encoded) == 0;
  ::close(fd);
  if (told) return detail::device_from_kernel(encoded);
#endif
  return st.st_rdev;
}

namespace {

// Both exist and are one file (hard links, symlinks followed), or one device under two nodes
// (a disk's too). Not std::filesystem::equivalent: libstdc++'s refuses to compare two devices
// or pipes (not_supported).
bool same_inode(const std::string& a, const std::string& b) {
  struct stat sa {};
  struct stat sb {};
  if (::stat(a.c_str(), &sa) != 0 || ::stat(b.c_str(), &sb) != 0) return false;
  if ((S_ISCHR(sa.st_mode) && S_ISCHR(sb.st_mode)) || (S_ISBLK(sa.st_mode) && S_ISBLK(sb.st_mode)))
    return detail::device_number(a) == detail::device_number(b);
  return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

// /dev/null, under any name: what two outputs write there is lost, not mixed.
bool discards(const std::string& path) {
  return same_inode(path, "/dev/null");
}

// A block device: what two outputs write there overwrites, as in a file.
bool is_disk(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISBLK(st.st_mode);
}

// The pseudo-terminal multiplexer (/dev/ptmx, /dev/pts/ptmx) makes a new terminal at each
// open: two outputs there share nothing.
bool opens_anew(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISCHR(st.st_mode) && st.st_rdev == makedev(5, 2);
}

// A path whose links to nothing (a name not made yet) are followed to where a write would
// make its file, as the write itself does (at most 40, the kernel's limit); `why` says why one
// could not be.
std::filesystem::path followed(std::filesystem::path path, std::string* why = nullptr) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (int links = 0; fs::is_symlink(fs::symlink_status(path, ec)) && !fs::exists(path, ec);
       ++links) {
    const fs::path target = fs::read_symlink(path, ec);
    if (links == 40 || ec) {
      if (why) *why = ec ? ec.message() : "too many levels of symbolic links";
      break;
    }
    path = target.is_absolute() ? target : path.parent_path() / target;
  }
  return path;
}

// A stream other than /dev/null (a terminal, a pipe: /dev/stdout) named by two outputs would
// take both, one after the other; an input and an output on one terminal are its reading and
// its writing.
bool same_file(const std::string& a, const std::string& b, bool both_outputs) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (discards(a) || discards(b) || opens_anew(a) || opens_anew(b)) return false;
  if (!both_outputs && (is_stream(a) || is_stream(b))) return false;
  if (same_inode(a, b)) return true;
  const fs::path ca = fs::weakly_canonical(fs::absolute(followed(a), ec), ec);
  if (ec) return false;
  const fs::path cb = fs::weakly_canonical(fs::absolute(followed(b), ec), ec);
  return !ec && ca == cb;
}

}  // namespace

// An unnamed file (O_TMPFILE; O_EXCL: never to be linked) is made where the system can: no
// name appears in the folder, so a program watching it sees nothing. On any failure (a
// filesystem or kernel without it: EOPNOTSUPP, EISDIR) a named file of our own making is
// tried, removed at once; a real failure fails there too.
std::string detail::cannot_make_file_in(const std::filesystem::path& folder, bool unnamed_first) {
#ifdef O_TMPFILE
  if (unnamed_first) {
    const int unnamed = ::open(folder.c_str(), O_TMPFILE | O_EXCL | O_WRONLY | O_CLOEXEC, 0600);
    if (unnamed >= 0) {
      ::close(unnamed);
      return {};
    }
  }
#endif
  std::string probe = (folder / ".fabrik-write-test-XXXXXX").string();
  const int fd = ::mkostemp(probe.data(), O_CLOEXEC);
  if (fd < 0) return std::strerror(errno);
  ::close(fd);
  ::unlink(probe.c_str());
  return {};
}

namespace {

// Why `path` cannot be written, or "": tried, since access() answers root yes where the
// write then fails (a read-only filesystem, /sys, /proc). An existing regular file is opened
// for appending, which changes nothing. For a new one, a file of our own making is made in
// its folder and removed (detail::cannot_make_file_in): the name itself is left alone, so another
// program making it meanwhile loses nothing. A link to nothing is followed to where the write would
// make its file. Other kinds (a pipe, a device) are left to the write: opening a pipe waits
// for its reader.
std::string cannot_write(const std::string& named) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (is_stream(named)) return {};
  const fs::file_status status = fs::status(named, ec);
  if (fs::exists(status)) {
    if (!fs::is_regular_file(status)) return {};
    const int fd = ::open(named.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
    if (fd < 0) return std::strerror(errno);
    ::close(fd);
    return {};
  }
  std::string why;
  const fs::path path = followed(named, &why);
  if (!why.empty()) return why;
  const fs::path where = path.has_parent_path() ? path.parent_path() : ".";
  // A name in /dev that is no device is a typo of one (/dev/nul): the write would make a
  // regular file there.
  if (fs::weakly_canonical(fs::absolute(where, ec), ec) == "/dev") return "no such device in /dev";
  return detail::cannot_make_file_in(where);
}

}  // namespace

void require_distinct_files(const std::vector<NamedFile>& files) {
  for (std::size_t i = 0; i < files.size(); ++i)
    for (std::size_t j = i + 1; j < files.size(); ++j) {
      const NamedFile& a = files[i];
      const NamedFile& b = files[j];
      if (a.path.empty() || b.path.empty() || !(a.output || b.output)) continue;
      const bool both_outputs = a.output && b.output;
      if (!same_file(a.path, b.path, both_outputs)) continue;
      if (const std::string kind = stream_kind(b.path); !kind.empty() && !is_disk(b.path))
        throw std::invalid_argument(
            a.option + " and " + b.option + " name the same " + kind + " ('" + a.path + "'" +
            (a.path == b.path ? "" : " and '" + b.path + "'") +
            "): both would be mixed into one stream. Fix: give each its own file (/dev/null "
            "and /dev/ptmx may take several)");
      throw std::invalid_argument(a.option + " and " + b.option + " name the same file '" + b.path +
                                  "': " + (both_outputs ? "one" : "the output") +
                                  " would overwrite the other. Fix: give each its own file");
    }
}

void require_output_folders(const std::vector<NamedFile>& files) {
  namespace fs = std::filesystem;
  for (const NamedFile& f : files) {
    if (!f.output || f.path.empty()) continue;
    std::error_code ec;
    const fs::path path(f.path);
    if (fs::is_directory(path, ec))
      throw std::invalid_argument(f.option + ": '" + f.path +
                                  "' is a folder. Fix: name a file in it");
    const fs::path folder = path.has_parent_path() ? path.parent_path() : fs::path(".");
    if (!fs::is_directory(folder, ec))
      throw std::invalid_argument(
          f.option + ": '" + f.path + "': the folder '" + folder.string() +
          (fs::exists(folder, ec) ? "' is not a folder" : "' does not exist") +
          ". Fix: create it, or write elsewhere");
    if (const std::string why = cannot_write(f.path); !why.empty())
      throw std::invalid_argument(f.option + ": '" + f.path + "' cannot be written (" + why +
                                  "). Fix: write elsewhere");
  }
}

void require_usable_outputs(const std::vector<NamedFile>& files) {
  require_output_folders(files);
  require_distinct_files(files);
}

}  // namespace fabrik::tools
