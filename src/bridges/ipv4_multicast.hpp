// Whether a text is an IPv4 multicast group, for the NatNet client's config and the simulated
// Motive: a unicast address there made the client's join fail at every retry and the server
// send its "group" frames to one host.
#pragma once

#include <arpa/inet.h>

#include <string>

namespace fabrik::bridges {

// What is wrong with `dotted` as a multicast group, or "" for a dotted IPv4 address in
// 224.0.0.0/4 (224.0.0.0 to 239.255.255.255). Names are not resolved.
inline std::string multicast_group_problem(const std::string& dotted) {
  in_addr a{};
  if (inet_pton(AF_INET, dotted.c_str(), &a) != 1)
    return "'" + dotted +
           "' is not a dotted IPv4 address (four numbers 0-255, no leading zeros, no host name)";
  if ((ntohl(a.s_addr) >> 28) != 0xE)
    return "'" + dotted + "' is not an IPv4 multicast group (224.0.0.0 to 239.255.255.255)";
  return {};
}

}  // namespace fabrik::bridges
