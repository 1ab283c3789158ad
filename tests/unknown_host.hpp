// A host name no resolver knows, for tests of what fabrikd and fabrik view say of one.
#pragma once

#include <netdb.h>

#include <chrono>
#include <string>

namespace fabrik::test {

// RFC 6761 reserves .invalid: no resolver finds it.
inline constexpr const char* kUnknownHost = "nohost.invalid";

// Empty when this machine's resolver says kUnknownHost does not exist, and says it quickly
// (fabrikd waits 500 ms for it): the tests can run. Else why they cannot (a resolver that
// fails or times out says nothing of the name).
inline std::string resolver_cannot_answer() {
  const auto start = std::chrono::steady_clock::now();
  addrinfo* found = nullptr;
  const int lookup = ::getaddrinfo(kUnknownHost, nullptr, nullptr, &found);
  if (found) ::freeaddrinfo(found);
  const auto took = std::chrono::steady_clock::now() - start;
  if (lookup != EAI_NONAME)
    return std::string("this machine's resolver cannot answer now (") + ::gai_strerror(lookup) +
           ")";
  if (took > std::chrono::milliseconds(250))
    return "this machine's resolver took over 250 ms to answer";
  return "";
}

}  // namespace fabrik::test
