// fabrikd's NatNet client: streams OptiTrack Motive's frames of data into a
// FrameSink, on the caller's thread, until asked to stop.
//
// One connection: a UDP command socket sends NAT_CONNECT to host:command_port;
// the NAT_SERVERINFO reply gives the NatNet version (3.x and 4.x are read,
// anything else is refused) and whether Motive streams multicast or unicast;
// NAT_REQUEST_MODELDEF gives the marker sets, whose markers become the labels
// (`Set:Marker`, see natnet_marker_table.hpp for how marker sets and
// labelled markers combine). Frames then arrive on the data port joined to
// the multicast group, or, in unicast, on the command socket itself (Motive
// answers the address the NAT_CONNECT came from), which then sends
// NAT_KEEPALIVE every second as the SDK's clients do. A frame whose "tracked
// models changed" flag is set, or that names a model not described, holds
// delivery until fresh model definitions arrive.
//
// Any failure (no reply, wrong version, a malformed, truncated or oversized
// datagram, no frame for stall_timeout_s, Motive's NAT_DISCONNECT) is
// recorded in SourceStatus, the connection is dropped, and a new handshake
// follows a Backoff wait. Never throws, never logs; waits are sliced to
// 100 ms so a stop request is seen promptly.
#pragma once

#include <cstdint>
#include <stop_token>
#include <string>

#include "bridges/source.hpp"

namespace fabrik::bridges {

struct NatNetClientOptions {
  std::string host;  // Motive's address (name or dotted quad)
  std::uint16_t command_port = 1510;
  std::uint16_t data_port = 1511;
  bool multicast = true;  // must match Motive's "Transmission Type"
  std::string multicast_group = "239.255.42.99";
  std::string local_interface = "0.0.0.0";  // where to bind and join the group
  ConnectionPolicy policy;
};

void run_natnet_client(const NatNetClientOptions& options, FrameSink& sink, SourceStatus& status,
                       std::stop_token stop);

}  // namespace fabrik::bridges
