// Whether a text is an IPv4 multicast group, for the NatNet client's config and the simulated
// Motive: a unicast address there made the client's join fail at every retry and the server
// send its "group" frames to one host.
#pragma once

#include <arpa/inet.h>

#include <string>

namespace fabrik::bridges {

// A dotted IPv4 address in 224.0.0.0/4 (224.0.0.0 to 239.255.255.255); names are not resolved.
inline bool ipv4_multicast(const std::string& dotted) {
  in_addr a{};
  if (inet_pton(AF_INET, dotted.c_str(), &a) != 1) return false;
  return (ntohl(a.s_addr) >> 28) == 0xE;
}

inline constexpr const char* kMulticastRange = "224.0.0.0 to 239.255.255.255";

}  // namespace fabrik::bridges
