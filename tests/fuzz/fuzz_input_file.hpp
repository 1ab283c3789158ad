// The fuzz input as a file, for entry points that take a path: an anonymous
// memory file (memfd), rewritten for every input and opened through
// /proc/self/fd/N, so the readers are fuzzed as they are used, nothing is
// written to disk and nothing is left behind when the fuzzer stops.
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <cstdint>
#include <string>

#include "fuzz_check.hpp"

namespace fabrik::fuzz {

class InputFile {
 public:
  InputFile() : fd_(memfd_create("fabrik-fuzz-input", MFD_CLOEXEC)) {
    require(fd_ >= 0, "memfd_create failed");
    path_ = "/proc/self/fd/" + std::to_string(fd_);
  }
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;
  ~InputFile() { close(fd_); }

  // Replaces the file's content with `data` and returns its path.
  const std::string& write(const std::uint8_t* data, std::size_t size) {
    require(ftruncate(fd_, 0) == 0, "ftruncate of the memory file failed");
    std::size_t done = 0;
    while (done < size) {
      const ssize_t n = pwrite(fd_, data + done, size - done, static_cast<off_t>(done));
      require(n > 0, "pwrite to the memory file failed");
      done += static_cast<std::size_t>(n);
    }
    return path_;
  }

 private:
  int fd_;
  std::string path_;
};

}  // namespace fabrik::fuzz
