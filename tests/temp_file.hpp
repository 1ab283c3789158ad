// A unique path under the temp directory, removed (with any sibling files a
// test names) when the test ends.
#pragma once

#include <filesystem>
#include <random>
#include <string>
#include <vector>

namespace fabrik::test {

class TempFile {
 public:
  explicit TempFile(const std::string& suffix, const std::string& prefix = "fabrik_test_") {
    static std::mt19937_64 rng{std::random_device{}()};
    path_ = (std::filesystem::temp_directory_path() / (prefix + std::to_string(rng()) + suffix))
                .string();
    remove_.push_back(path_);
  }
  ~TempFile() {
    std::error_code ec;
    for (const std::string& p : remove_) std::filesystem::remove(p, ec);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  const std::string& path() const { return path_; }
  // Another file the code under test writes beside this one.
  void also_remove(const std::string& path) { remove_.push_back(path); }

 private:
  std::string path_;
  std::vector<std::string> remove_;
};

}  // namespace fabrik::test
