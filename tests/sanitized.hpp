// FABRIK_TEST_SANITIZED is defined in a build with AddressSanitizer (gcc or
// clang), where the code runs several times slower: time bounds widen there.
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define FABRIK_TEST_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define FABRIK_TEST_SANITIZED 1
#endif
#endif

#include <chrono>

namespace fabrik::test {
// A time bound: `release` in a normal build, `sanitized` under the sanitizers.
constexpr std::chrono::milliseconds time_bound(std::chrono::milliseconds release,
                                               std::chrono::milliseconds sanitized) {
#if defined(FABRIK_TEST_SANITIZED)
  (void)release;
  return sanitized;
#else
  (void)sanitized;
  return release;
#endif
}
}  // namespace fabrik::test
