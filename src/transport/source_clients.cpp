// make_source_client: the config's source as a vendor client (src/bridges).
#include "bridges/natnet_client.hpp"
#include "bridges/qtm/client.hpp"
#include "source_input.hpp"

namespace fabrik::wire {

SourceClient make_source_client(const SourceConfig& source) {
  switch (source.kind) {
    case SourceKind::qtm: {
      qtm::QtmClientOptions o;
      o.host = source.host;
      o.port = source.port;
      o.frequency_divisor = source.frequency_divisor;
      o.policy = source.policy;
      return [o](bridges::FrameSink& sink, bridges::SourceStatus& status, std::stop_token stop) {
        qtm::run_qtm_client(o, sink, status, stop);
      };
    }
    case SourceKind::natnet: {
      bridges::NatNetClientOptions o;
      o.host = source.host;
      o.command_port = source.port;
      o.data_port = source.data_port;
      o.multicast = source.multicast;
      o.multicast_group = source.multicast_group;
      o.local_interface = source.local_interface;
      o.policy = source.policy;
      return [o](bridges::FrameSink& sink, bridges::SourceStatus& status, std::stop_token stop) {
        bridges::run_natnet_client(o, sink, status, stop);
      };
    }
    case SourceKind::none:
      break;
  }
  return [](bridges::FrameSink&, bridges::SourceStatus& status, std::stop_token) {
    status.error("no source configured");
  };
}

}  // namespace fabrik::wire
