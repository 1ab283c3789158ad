// The JSON fast path of MarkerDecoder (src/transport/marker_json_fast.hpp)
// against the full reader on many varied payloads: the same verdict, the
// same error message, the same frame bit for bit. The fast path takes the
// common shape and declines the rest, so it cannot silently diverge.
#include <algorithm>
#include <bit>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "transport/marker_codec.hpp"

using namespace fabrik::wire;

namespace {

std::span<const std::uint8_t> bytes(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// Random payloads, most of the common shape, some not, some malformed.
class PayloadMaker {
 public:
  PayloadMaker(std::vector<std::string> names, std::vector<std::string> unknown,
               std::vector<std::string> sensors, unsigned seed)
      : names_(std::move(names)), unknown_(std::move(unknown)), sensors_(std::move(sensors)),
        rng_(seed) {}

  std::string payload() {
    std::string s = ws() + "{";
    std::vector<std::string> members;
    if (chance(95)) members.push_back(kv("frame", frame_number()));
    if (chance(70)) members.push_back(kv("time", number()));
    if (chance(30)) members.push_back(kv("stamp_us", number()));
    if (chance(70)) members.push_back(kv("units", units()));
    if (chance(95)) members.push_back(kv("markers", markers()));
    if (chance(5)) members.push_back(kv("markers", markers()));  // a duplicate key
    if (chance(5)) members.push_back(kv("frame", frame_number()));
    if (chance(4)) members.push_back(kv("extra", "[1, {\"a\": null}]"));
    if (chance(4)) members.push_back(kv("orientations", orientations()));
    std::shuffle(members.begin(), members.end(), rng_);
    for (std::size_t i = 0; i < members.size(); ++i) s += (i ? "," : "") + ws() + members[i] + ws();
    s += "}" + ws();
    if (chance(10)) mutate(s);
    return s;
  }

 private:
  bool chance(int percent) { return static_cast<int>(rng_() % 100) < percent; }
  template <class T>
  const T& pick(const std::vector<T>& v) {
    return v[rng_() % v.size()];
  }
  std::string ws() {
    static const std::vector<std::string> spaces = {"", "", "", " ", "\n", "\t", "\r\n  "};
    return pick(spaces);
  }
  std::string kv(const std::string& key, const std::string& value) {
    return "\"" + key + "\"" + ws() + ":" + ws() + value;
  }
  std::string units() {
    static const std::vector<std::string> odd = {"\"cm\"", "\"m\\u006d\"", "null", "1"};
    return chance(90) ? (chance(50) ? "\"mm\"" : "\"m\"") : pick(odd);
  }
  std::string frame_number() {
    static const std::vector<std::string> odd = {"0", "-0", "-3", "1.5", "1e2", "\"12\"",
                                                 "18446744073709551615", "18446744073709551616",
                                                 "007", "null"};
    return chance(90) ? std::to_string(rng_() % 100000000) : pick(odd);
  }
  // Numbers in every format JSON allows (and some it does not).
  std::string number() {
    std::uniform_real_distribution<double> mm(-3000.0, 3000.0);
    char text[64];
    static const std::vector<std::string> odd = {
        "-0", "-0.0", "0.0000", "0", "1e400", "-1e400", "1e-400", "4.9e-324",
        "9007199254740993", "9007199254740993.0", "9007199254740992.5", "0.30000000000000004",
        "18446744073709551616", "-9223372036854775808", "-9223372036854775809",
        "1.7976931348623157e308", "123.456e-2", "1E+2", "01", "1.", ".5", "+1", "-", "NaN",
        "1e", "\"2\"", "true", "null", "0.1234567890123456789012345"};
    if (chance(2)) return pick(odd);  // rare, as each one decides its whole payload
    switch (rng_() % 8) {
      case 0:
      case 1:
      case 2:
      case 3:
        std::snprintf(text, sizeof text, "%.*f", static_cast<int>(rng_() % 8), mm(rng_));
        return text;
      case 4:
        return std::to_string(static_cast<long long>(mm(rng_)));
      case 5:
        std::snprintf(text, sizeof text, rng_() % 2 ? "%.*e" : "%.*E", static_cast<int>(rng_() % 17),
                      mm(rng_) * std::pow(10.0, static_cast<int>(rng_() % 40) - 20));
        return text;
      case 6:
        std::snprintf(text, sizeof text, "%.*f", 12 + static_cast<int>(rng_() % 12), mm(rng_) / 1e3);
        return text;
      default: {
        std::string digits = rng_() % 2 ? "-" : "";
        digits += std::to_string(1 + rng_() % 9);
        for (int i = static_cast<int>(rng_() % 24); i > 0; --i) digits += std::to_string(rng_() % 10);
        if (chance(70)) {
          digits += ".";
          for (int i = 1 + static_cast<int>(rng_() % 24); i > 0; --i)
            digits += std::to_string(rng_() % 10);
        }
        return digits;
      }
    }
  }
  std::string name() {
    if (chance(5)) return pick(unknown_);
    return pick(names_);
  }
  std::string markers() {
    if (chance(2)) return pick(std::vector<std::string>{"[1, 2]", "null", "\"x\""});
    std::string s = "{";
    std::vector<std::string> order = names_;
    // Half the time in the names' order (the name index's previous-frame hints hit).
    if (chance(50)) std::shuffle(order.begin(), order.end(), rng_);
    order.resize(rng_() % (order.size() + 1));
    for (int extra = static_cast<int>(rng_() % 3); extra > 0; --extra)
      order.insert(order.begin() + static_cast<long>(rng_() % (order.size() + 1)), name());
    for (std::size_t i = 0; i < order.size(); ++i) {
      s += (i ? "," : "") + ws() + kv(order[i], marker_value()) + ws();
    }
    return s + "}";
  }
  std::string marker_value() {
    if (chance(15)) return "null";
    const int count = chance(85) ? 3 : chance(80) ? 4 : static_cast<int>(rng_() % 6);
    std::string s = "[" + ws();
    for (int k = 0; k < count; ++k) s += (k ? "," : "") + ws() + number() + ws();
    return s + "]";
  }
  std::string orientations() {
    std::string s = "{";
    for (std::size_t i = 0; i < sensors_.size(); ++i)
      s += (i ? ", " : "") + kv(sensors_[i], chance(20) ? "null" : "[1, 0, 0, 0]");
    return s + "}";
  }
  void mutate(std::string& s) {
    static const std::string alphabet = "{}[]:,\" \\-+.eE0123456789tfnulx\x01\xc3\xa9\xff";
    const std::size_t at = rng_() % (s.size() + 1);
    switch (rng_() % 3) {
      case 0:
        if (at < s.size()) s[at] = alphabet[rng_() % alphabet.size()];
        break;
      case 1:
        s.insert(at, 1, alphabet[rng_() % alphabet.size()]);
        break;
      default:
        s.resize(at);
        break;
    }
  }

  std::vector<std::string> names_, unknown_, sensors_;
  std::mt19937 rng_;
};

std::uint64_t bits(double v) { return std::bit_cast<std::uint64_t>(v); }

// Everything a decode leaves in the frame, bit for bit.
void require_same_frame(const MarkerFrame& a, const MarkerFrame& b) {
  REQUIRE(a.frame == b.frame);
  REQUIRE(a.has_time == b.has_time);
  REQUIRE(bits(a.time_s) == bits(b.time_s));
  REQUIRE(a.has_stamp == b.has_stamp);
  if (a.has_stamp) REQUIRE(bits(a.stamp_us) == bits(b.stamp_us));
  REQUIRE(a.visible == b.visible);
  REQUIRE(a.confidence == b.confidence);
  REQUIRE(a.confidence_count == b.confidence_count);
  for (std::size_t i = 0; i < a.p_world_m.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      CAPTURE(i, k, a.p_world_m[i][k], b.p_world_m[i][k]);
      REQUIRE(bits(a.p_world_m[i][k]) == bits(b.p_world_m[i][k]));
    }
  REQUIRE(a.rejected_count == b.rejected_count);
  REQUIRE(a.zero_count == b.zero_count);
  REQUIRE(a.known_count == b.known_count);
  REQUIRE(a.unknown_count == b.unknown_count);
  REQUIRE(a.unknown_listed == b.unknown_listed);
  for (int k = 0; k < a.unknown_listed; ++k) REQUIRE(a.unknown_names[k] == b.unknown_names[k]);
  REQUIRE(a.sensor_visible == b.sensor_visible);
  REQUIRE(a.rejected_orientations == b.rejected_orientations);
  REQUIRE(a.unknown_sensor_count == b.unknown_sensor_count);
}

}  // namespace

TEST_CASE("The JSON fast path decodes every payload as the full reader does", "[codec][fast]") {
  const std::vector<std::string> names = {"LASI", "RASI", "LPSI", "RPSI", "LKNE", "RKNE",
                                          "LTOE", "R.Heel", "with space", "\xc3\xa9paule",
                                          "Subject:left_lateral_epicondyle_long_name", "LASI"};
  const std::vector<std::string> unknown = {"X", "boite:gauche_exterieur", "\xc3\xa9t\xc3\xa9",
                                            "esc\\\"aped", "L\\u0041SI", ""};
  const std::vector<std::string> sensors = {"S0", "S1"};
  MarkerDecoder fast(names, 1e-3, 1 << 20, {}, sensors), full(names, 1e-3, 1 << 20, {}, sensors);
  full.set_json_fast_path(false);
  MarkerFrame a = fast.make_frame(), b = full.make_frame();
  PayloadMaker maker(names, unknown, sensors, 2026);
  int accepted = 0, refused = 0;
  for (int n = 0; n < 40000; ++n) {
    const std::string p = maker.payload();
    CAPTURE(n, p);
    fast.set_json_fast_path(true);  // no pause after a declined payload: try every one
    std::string error_a, error_b;
    const bool ok_a = fast.decode(bytes(p), a, error_a);
    const bool ok_b = full.decode(bytes(p), b, error_b);
    REQUIRE(ok_a == ok_b);
    REQUIRE(error_a == error_b);
    require_same_frame(a, b);
    (ok_a ? accepted : refused) += 1;
  }
  // Both outcomes were exercised, and the fast path took most payloads.
  CAPTURE(accepted, refused, fast.json_fast_path_frames());
  CHECK(accepted > 15000);
  CHECK(refused > 10000);
  CHECK(fast.json_fast_path_frames() > 10000);
  CHECK(full.json_fast_path_frames() == 0);
}

TEST_CASE("After payloads the fast path declines it takes the common shape again",
          "[codec][fast]") {
  const std::vector<std::string> names = {"A", "B"};
  MarkerDecoder d(names, 1e-3, 1 << 20);
  MarkerFrame f = d.make_frame();
  std::string error;
  const std::string common = R"({"frame": 1, "markers": {"A": [1, 2, 3], "B": null}})";
  const std::string unusual = R"({"frame": 1, "extra": 0, "markers": {"A": [1, 2, 3]}})";
  for (int i = 0; i < 10; ++i) REQUIRE(d.decode(bytes(common), f, error));
  CHECK(d.json_fast_path_frames() == 10);
  for (int i = 0; i < 64; ++i) REQUIRE(d.decode(bytes(unusual), f, error));
  CHECK(f.visible == std::vector<std::uint8_t>{1, 0});
  CHECK(d.json_fast_path_frames() == 10);  // tried on 4 of them (0, 16, 32, 48), all declined
  // Back to the common shape: the pause after the 48th is over by the 64th.
  for (int i = 0; i < 32; ++i) REQUIRE(d.decode(bytes(common), f, error));
  CHECK(d.json_fast_path_frames() == 10 + 32);
}
