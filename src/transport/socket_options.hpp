// What a fabrikd input (SUB) or output (XPUB) socket is given: its options,
// queue limits and kernel buffers (docs/overload.md). The daemon
// opens its sockets with these, and so does `fabrik bench latency`'s ZeroMQ
// floor (src/bench/zmq_floor.cpp), so the floor cannot drift from the daemon.
// The limits' constants and their reasons are in daemon.hpp ("Transport limits").
#pragma once

#include <zmq.hpp>

#include "config/daemon_config.hpp"

namespace fabrik::wire {

// Every option of the input socket, set before bind/connect so that it
// holds for every connection.
void set_input_options(zmq::socket_t& s, const DaemonConfig& c);
// Its options that follow the config (message size, queue): set again on a
// socket kept across a reload, they hold for connections made from then on.
void set_input_limits(zmq::socket_t& s, const DaemonConfig& c);

// Every option of the output socket, set before bind/connect.
void set_output_options(zmq::socket_t& s, const DaemonConfig& c);
// Its options that follow the config (the subscribers' queue).
void set_output_limits(zmq::socket_t& s, const DaemonConfig& c);

}  // namespace fabrik::wire
