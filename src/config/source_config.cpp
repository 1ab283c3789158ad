#include "source_config.hpp"

#include <charconv>

#include "bridges/ipv4_multicast.hpp"

namespace fabrik {

namespace {

constexpr std::uint16_t kQtmLittleEndianPort = 22223;  // QTM RT protocol, docs/qtm-rt-protocol.md
constexpr std::uint16_t kNatNetCommandPort = 1510;

// "scheme://host[:port]"; IPv6 literals in brackets ("[::1]:22223").
void read_url(const JsonReader& r, SourceConfig& c) {
  const std::string url = r.as_string();
  const std::string fix =
      "write \"qtm://HOST[:PORT]\" (QTM's RT protocol, port 22223) or "
      "\"natnet://HOST[:COMMAND_PORT]\" (OptiTrack Motive, port 1510)";
  const std::size_t sep = url.find("://");
  if (sep == std::string::npos) r.fail("'" + url + "' is not a source URL", fix);
  const std::string scheme = url.substr(0, sep);
  if (scheme == "qtm") {
    c.kind = SourceKind::qtm;
    c.port = kQtmLittleEndianPort;
  } else if (scheme == "natnet") {
    c.kind = SourceKind::natnet;
    c.port = kNatNetCommandPort;
  } else {
    r.fail("unknown source '" + scheme + "'", fix);
  }
  std::string rest = url.substr(sep + 3);
  if (!rest.empty() && rest.back() == '/') rest.pop_back();
  std::string port_text;
  if (rest.starts_with("[")) {
    const std::size_t close = rest.find(']');
    if (close == std::string::npos) r.fail("'" + url + "': unclosed '[' in the host", fix);
    c.host = rest.substr(1, close - 1);
    if (close + 1 < rest.size()) {
      if (rest[close + 1] != ':') r.fail("'" + url + "': expected ':PORT' after ']'", fix);
      port_text = rest.substr(close + 2);
    }
  } else {
    const std::size_t colon = rest.rfind(':');
    c.host = rest.substr(0, colon);
    if (colon != std::string::npos) port_text = rest.substr(colon + 1);
  }
  if (c.host.empty()) r.fail("'" + url + "' names no host", fix);
  // An IPv6 literal: NatNet's client is IPv4 only (docs/vendor-sources.md), and one without
  // brackets would be split at its last ':' into a host and a port. Either would pass here and
  // then fail to resolve at every retry, for as long as the daemon runs.
  const bool ipv6 = rest.starts_with("[") || c.host.find(':') != std::string::npos;
  if (c.kind == SourceKind::natnet && ipv6)
    r.fail("'" + url + "': NatNet is IPv4 only, and this is an IPv6 address",
           "give Motive's IPv4 address or host name, e.g. \"natnet://192.168.1.10\"");
  if (ipv6 && !rest.starts_with("["))
    r.fail("'" + url + "': an IPv6 address goes in brackets",
           "write e.g. \"qtm://[::1]\" or \"qtm://[fe80::1]:22223\"");
  if (c.host.find_first_of("/?#@ ") != std::string::npos)
    r.fail("'" + url + "': the host '" + c.host + "' is not a host name or address", fix);
  if (!port_text.empty() || (rest.find(':') != std::string::npos && !rest.starts_with("["))) {
    unsigned value = 0;
    const auto [end, ec] =
        std::from_chars(port_text.data(), port_text.data() + port_text.size(), value);
    if (ec != std::errc{} || end != port_text.data() + port_text.size() || value == 0 ||
        value > 65535)
      r.fail("'" + url + "': the port '" + port_text + "' is not a number in 1..65535", fix);
    c.port = static_cast<std::uint16_t>(value);
  }
  c.url = url;
}

}  // namespace

SourceConfig read_source_config(const JsonReader& input) {
  SourceConfig c;
  if (!input.has("source")) {
    if (input.has("source_options"))
      input.at("source_options").fail("source_options without a source",
                                      "add \"source\": \"qtm://HOST\" or \"natnet://HOST\", or "
                                      "remove source_options");
    return c;
  }
  read_url(input.at("source"), c);
  if (!input.has("source_options")) return c;
  const JsonReader o = input.at("source_options");
  o.expect_object();
  o.only_keys({"subject_prefix", "axes", "frequency_divisor", "natnet_data", "multicast_group",
               "data_port", "local_interface", "connect_timeout_s", "reply_timeout_s",
               "stall_timeout_s", "reconnect_min_s", "reconnect_max_s"});
  const auto only_for = [&](const char* key, SourceKind kind, const char* name) {
    if (o.has(key) && c.kind != kind)
      o.at(key).fail(std::string(key) + " applies to " + name + " sources only",
                     "remove it, or use a " + std::string(name) + " source");
  };
  only_for("frequency_divisor", SourceKind::qtm, "qtm://");
  for (const char* key : {"natnet_data", "multicast_group", "data_port", "local_interface"})
    only_for(key, SourceKind::natnet, "natnet://");
  c.subject_prefix = o.get("subject_prefix", c.subject_prefix);
  if (o.has("axes"))
    c.axes = read_whole_lab_axes(
        o.at("axes"), "the server's up axis is x and no forward axis is given",
        "add \"forward\": \"+y\" or \"+z\" (the server's axis pointing forward)");
  c.frequency_divisor =
      static_cast<int>(o.get("frequency_divisor", static_cast<long long>(1), 1LL, 1000LL));
  if (o.has("natnet_data"))
    c.multicast = read_choice<bool>(o.at("natnet_data"), "NatNet data channel",
                                    {{"multicast", true}, {"unicast", false}});
  c.multicast_group = o.get("multicast_group", c.multicast_group);
  // Refused in unicast too (as the schema does): a group given is meant to be one.
  if (const std::string problem = bridges::multicast_group_problem(c.multicast_group);
      !problem.empty())
    (o.has("multicast_group") ? o.at("multicast_group") : o)
        .fail(problem,
              "give Motive's group (Streaming > Multicast Interface; its default is "
              "239.255.42.99), or leave it out");
  c.data_port = static_cast<std::uint16_t>(
      o.get("data_port", static_cast<long long>(c.data_port), 1LL, 65535LL));
  c.local_interface = o.get("local_interface", c.local_interface);
  c.policy.connect_timeout_s = o.get("connect_timeout_s", c.policy.connect_timeout_s, 0.01, 600.0);
  c.policy.reply_timeout_s = o.get("reply_timeout_s", c.policy.reply_timeout_s, 0.01, 600.0);
  c.policy.stall_timeout_s = o.get("stall_timeout_s", c.policy.stall_timeout_s, 0.05, 3600.0);
  c.policy.reconnect_min_s = o.get("reconnect_min_s", c.policy.reconnect_min_s, 0.001, 600.0);
  c.policy.reconnect_max_s = o.get("reconnect_max_s", c.policy.reconnect_max_s, c.policy.reconnect_min_s, 3600.0);
  return c;
}

}  // namespace fabrik
