// "input.source" and "input.source_options" of the daemon config
// (docs/daemon-config.md, "Vendor sources"): a QTM or NatNet server that
// fabrikd connects to itself, beside its ZeroMQ marker input.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "bridges/source.hpp"
#include "json_reader.hpp"
#include "lab_axes_json.hpp"

namespace fabrik {

enum class SourceKind { none, qtm, natnet };

struct SourceConfig {
  SourceKind kind = SourceKind::none;
  std::string url;  // as written, e.g. "qtm://10.0.0.5:22223"
  std::string host;
  std::uint16_t port = 0;  // QTM: the RT port (22223); NatNet: the command port (1510)

  // QTM: stream every frame (1) or every n-th (QTM's "Frequency divisor").
  int frequency_divisor = 1;
  // NatNet's data channel.
  bool multicast = true;
  std::string multicast_group = "239.255.42.99";
  std::uint16_t data_port = 1511;
  std::string local_interface = "0.0.0.0";

  // Taken off the front of every marker name before it is matched to the
  // model: "*" (default) strips everything up to the last ':' (NatNet's
  // "Subject:Marker"), "" strips nothing, any other text strips exactly it.
  std::string subject_prefix = "*";
  // The server's axes; absent: QTM's are the lab's own, NatNet's Motive's
  // Y-up (forward +x). Positions are rotated from these into the model's lab axes.
  std::optional<LabAxes> axes;

  // Timeouts and reconnection backoff; the defaults are the bridges' own.
  bridges::ConnectionPolicy policy;

  bool operator==(const SourceConfig&) const = default;
};

// Reads "source" (a URL) and "source_options" of an "input" object; throws ConfigError.
SourceConfig read_source_config(const JsonReader& input);

}  // namespace fabrik
