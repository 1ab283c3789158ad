// A host name no resolver knows, for tests of what fabrikd and fabrik view say of one.
#pragma once

#include <netdb.h>

#include <string>

namespace fabrik::test {

// RFC 6761 reserves .invalid: no resolver finds it.
inline constexpr const char* kUnknownHost = "nohost.invalid";

// Empty when this machine's resolver says kUnknownHost does not exist (the tests can run), else
// why they cannot (a resolver that fails or times out says nothing of the name).
inline std::string resolver_cannot_answer() {
  addrinfo* found = nullptr;
  const int lookup = ::getaddrinfo(kUnknownHost, nullptr, nullptr, &found);
  if (found) ::freeaddrinfo(found);
  return lookup == EAI_NONAME ? std::string()
                              : std::string("this machine's resolver cannot answer now (") +
                                    ::gai_strerror(lookup) + ")";
}

}  // namespace fabrik::test
