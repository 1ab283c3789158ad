// The fast paths of MarkerDecoder (src/transport/marker_json_fast.hpp and
// marker_msgpack_fast.hpp) against the full reader on many varied payloads:
// the same verdict, the same error message, the same frame bit for bit. A
// fast path takes the common shape and declines the rest, so it cannot
// silently diverge.
#include <algorithm>
#include <bit>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
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

// What both payload makers draw with.
class RandomChoices {
 protected:
  explicit RandomChoices(unsigned seed) : rng_(seed) {}
  bool chance(int percent) { return static_cast<int>(rng_() % 100) < percent; }
  template <class T>
  const T& pick(const std::vector<T>& v) {
    return v[rng_() % v.size()];
  }
  std::mt19937 rng_;
};

// Random payloads, most of the common shape, some not, some malformed.
class PayloadMaker : RandomChoices {
 public:
  PayloadMaker(std::vector<std::string> names, std::vector<std::string> unknown,
               std::vector<std::string> sensors, unsigned seed)
      : RandomChoices(seed),
        names_(std::move(names)),
        unknown_(std::move(unknown)),
        sensors_(std::move(sensors)) {}

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
  REQUIRE(a.has_subject == b.has_subject);
  REQUIRE(a.subject == b.subject);
}

// Decodes `count` payloads of `maker` with the fast path and with the full
// reader alone: the same verdict, message and frame every time.
struct Verdicts {
  int accepted = 0, refused = 0;
  std::uint64_t fast_path_frames = 0;
};
template <class Maker>
Verdicts decode_both_ways(Maker& maker, const std::vector<std::string>& names,
                          const std::vector<std::string>& sensors, int count) {
  MarkerDecoder fast(names, 1e-3, 1 << 20, {}, sensors), full(names, 1e-3, 1 << 20, {}, sensors);
  full.set_fast_path(false);
  MarkerFrame a = fast.make_frame(), b = full.make_frame();
  Verdicts v;
  for (int n = 0; n < count; ++n) {
    const std::string p = maker.payload();
    CAPTURE(n, p);
    fast.set_fast_path(true);  // no pause after a declined payload: try every one
    std::string error_a, error_b;
    const bool ok_a = fast.decode(bytes(p), a, error_a);
    const bool ok_b = full.decode(bytes(p), b, error_b);
    REQUIRE(ok_a == ok_b);
    REQUIRE(error_a == error_b);
    require_same_frame(a, b);
    (ok_a ? v.accepted : v.refused) += 1;
  }
  REQUIRE(full.fast_path_frames() == 0);
  v.fast_path_frames = fast.fast_path_frames();
  return v;
}

}  // namespace

TEST_CASE("The JSON fast path decodes every payload as the full reader does", "[codec][fast]") {
  const std::vector<std::string> names = {"LASI", "RASI", "LPSI", "RPSI", "LKNE", "RKNE",
                                          "LTOE", "R.Heel", "with space", "\xc3\xa9paule",
                                          "Subject:left_lateral_epicondyle_long_name", "LASI"};
  const std::vector<std::string> unknown = {"X", "boite:gauche_exterieur", "\xc3\xa9t\xc3\xa9",
                                            "esc\\\"aped", "L\\u0041SI", ""};
  const std::vector<std::string> sensors = {"S0", "S1"};
  PayloadMaker maker(names, unknown, sensors, 2026);
  const Verdicts v = decode_both_ways(maker, names, sensors, 40000);
  // Both outcomes were exercised, and the fast path took most payloads.
  CAPTURE(v.accepted, v.refused, v.fast_path_frames);
  CHECK(v.accepted > 15000);
  CHECK(v.refused > 10000);
  CHECK(v.fast_path_frames > 10000);
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
  CHECK(d.fast_path_frames() == 10);
  for (int i = 0; i < 64; ++i) REQUIRE(d.decode(bytes(unusual), f, error));
  CHECK(f.visible == std::vector<std::uint8_t>{1, 0});
  CHECK(d.fast_path_frames() == 10);  // tried on 4 of them (0, 16, 32, 48), all declined
  // Back to the common shape: the pause after the 48th is over by the 64th.
  for (int i = 0; i < 32; ++i) REQUIRE(d.decode(bytes(common), f, error));
  CHECK(d.fast_path_frames() == 10 + 32);
}

namespace {

// Random MessagePack payloads: most of the common shape, in every encoding
// MessagePack allows for each value, some of other shapes, some malformed.
class MsgpackMaker : RandomChoices {
 public:
  MsgpackMaker(std::vector<std::string> names, std::vector<std::string> unknown, unsigned seed)
      : RandomChoices(seed), names_(std::move(names)), unknown_(std::move(unknown)) {}

  std::string payload() {
    std::vector<std::string> members;
    if (chance(95)) members.push_back(str("frame") + frame_number());
    if (chance(70)) members.push_back(str("time") + number());
    if (chance(30)) members.push_back(str("stamp_us") + number());
    if (chance(70)) members.push_back(str("units") + units());
    if (chance(10)) members.push_back(str("subject") + str(chance(50) ? "S1" : "a subject"));
    if (chance(95)) members.push_back(str("markers") + markers());
    if (chance(5)) members.push_back(str("markers") + markers());  // a duplicate key
    if (chance(5)) members.push_back(str("frame") + frame_number());
    if (chance(4)) members.push_back(str("extra") + "\x92\x01\xc0");  // [1, nil]
    if (chance(4)) members.push_back(str("orientations") + "\x81" + str("S0") + "\xc0");
    std::shuffle(members.begin(), members.end(), rng_);
    std::size_t count = members.size();
    if (chance(3)) count += chance(50) ? 1 : -1;  // a header that lies: truncated, or bytes left
    std::string s = header(count, 0x80, 0xde);
    for (const std::string& m : members) s += m;
    if (chance(10)) mutate(s);
    return s;
  }

 private:
  template <class T>
  static std::string big_endian(T v) {
    std::string s(sizeof(T), '\0');
    for (std::size_t k = 0; k < sizeof(T); ++k)
      s[sizeof(T) - 1 - k] = static_cast<char>((static_cast<std::uint64_t>(v) >> (8 * k)) & 0xff);
    return s;
  }
  static std::string byte(int b) { return std::string(1, static_cast<char>(b)); }
  // A map (first = 0x80) or array (first = 0x90) header, in the fix form or a wider one.
  std::string header(std::size_t n, int first, int tag16) {
    const int form = static_cast<int>(rng_() % 10);
    if (n < 16 && form < 8) return byte(first | static_cast<int>(n));
    if (n < 65536 && form < 9) return byte(tag16) + big_endian(static_cast<std::uint16_t>(n));
    return byte(tag16 + 1) + big_endian(static_cast<std::uint32_t>(n));
  }
  std::string str(const std::string& s) {
    const int form = static_cast<int>(rng_() % 10);
    std::string h;
    if (s.size() < 32 && form < 7)
      h = byte(0xa0 | static_cast<int>(s.size()));
    else if (s.size() < 256 && form < 8)
      h = byte(0xd9) + byte(static_cast<int>(s.size()));
    else if (form < 9)
      h = byte(0xda) + big_endian(static_cast<std::uint16_t>(s.size()));
    else
      h = byte(0xdb) + big_endian(static_cast<std::uint32_t>(s.size()));
    return h + s;
  }
  std::string unsigned_integer(std::uint64_t u) {
    const int form = static_cast<int>(rng_() % 5);
    if (u < 128 && form == 0) return byte(static_cast<int>(u));
    if (u < 256 && form <= 1) return byte(0xcc) + big_endian(static_cast<std::uint8_t>(u));
    if (u < 65536 && form <= 2) return byte(0xcd) + big_endian(static_cast<std::uint16_t>(u));
    if (u < (std::uint64_t{1} << 32) && form <= 3)
      return byte(0xce) + big_endian(static_cast<std::uint32_t>(u));
    return byte(0xcf) + big_endian(u);
  }
  std::string signed_integer(std::int64_t i) {
    const int form = static_cast<int>(rng_() % 5);
    if (i >= -32 && i < 0 && form == 0) return byte(static_cast<int>(i) & 0xff);
    if (i >= -128 && i < 128 && form <= 1) return byte(0xd0) + big_endian(static_cast<std::uint8_t>(i));
    if (i >= -32768 && i < 32768 && form <= 2)
      return byte(0xd1) + big_endian(static_cast<std::uint16_t>(i));
    if (i >= INT32_MIN && i <= INT32_MAX && form <= 3)
      return byte(0xd2) + big_endian(static_cast<std::uint32_t>(i));
    return byte(0xd3) + big_endian(static_cast<std::uint64_t>(i));
  }
  std::string float64(double v) { return byte(0xcb) + big_endian(std::bit_cast<std::uint64_t>(v)); }
  std::string float32(float v) { return byte(0xca) + big_endian(std::bit_cast<std::uint32_t>(v)); }
  std::string frame_number() {
    switch (rng_() % 20) {
      case 0: return signed_integer(static_cast<std::int64_t>(rng_() % 1000) - 500);
      case 1: return float64(12.0);
      case 2: return str("12");
      case 3: return "\xc0";
      default: return unsigned_integer(rng_() % 2 ? rng_() % 100000000 : rng_());
    }
  }
  // Numbers in every width MessagePack has, and values the readers must agree on.
  std::string number() {
    std::uniform_real_distribution<double> mm(-3000.0, 3000.0);
    const double v = mm(rng_);
    switch (rng_() % 12) {
      case 0: return unsigned_integer(static_cast<std::uint64_t>(std::fabs(v)));
      case 1: return signed_integer(static_cast<std::int64_t>(v));
      case 2: return float32(static_cast<float>(v));
      case 3: {
        static const std::vector<double> odd = {
            0.0, -0.0, std::nan(""), INFINITY, -INFINITY, 1e300, -1e300, 4.9e-324, 1e-5};
        return chance(50) ? float64(pick(odd)) : float32(static_cast<float>(pick(odd)));
      }
      case 4: return unsigned_integer(rng_());  // beyond 2^53
      case 5:
        if (chance(3)) return pick(std::vector<std::string>{"\xc0", "\xc3", "\xa1x", "\xc4\x01\x00"});
        return float64(v);
      default: return float64(v);
    }
  }
  std::string units() {
    static const std::vector<std::string> odd = {"cm", "M", ""};
    if (chance(5)) return chance(50) ? std::string("\xc0") : unsigned_integer(1);
    return str(chance(90) ? (chance(50) ? "mm" : "m") : pick(odd));
  }
  std::string markers() {
    if (chance(2)) return pick(std::vector<std::string>{"\x92\x01\x02", "\xc0", "\xa1x"});
    std::vector<std::string> order = names_;
    if (chance(50)) std::shuffle(order.begin(), order.end(), rng_);
    order.resize(rng_() % (order.size() + 1));
    for (int extra = static_cast<int>(rng_() % 3); extra > 0; --extra)
      order.insert(order.begin() + static_cast<long>(rng_() % (order.size() + 1)),
                   chance(5) ? pick(unknown_) : pick(names_));
    std::string s = header(order.size(), 0x80, 0xde);
    for (const std::string& name : order) s += str(name) + marker_value();
    return s;
  }
  std::string marker_value() {
    if (chance(15)) return "\xc0";
    const int count = chance(85) ? 3 : chance(80) ? 4 : static_cast<int>(rng_() % 6);
    std::string s = header(static_cast<std::size_t>(count), 0x90, 0xdc);
    for (int k = 0; k < count; ++k) s += k == 3 && chance(70) ? float64(std::uniform_real_distribution<double>(-0.2, 1.2)(rng_)) : number();
    return s;
  }
  void mutate(std::string& s) {
    const std::size_t at = rng_() % (s.size() + 1);
    switch (rng_() % 4) {
      case 0:
        if (at < s.size()) s[at] = static_cast<char>(rng_() & 0xff);
        break;
      case 1:
        s.insert(at, 1, static_cast<char>(rng_() & 0xff));
        break;
      case 2:
        s.resize(at);
        break;
      default:
        s += byte(static_cast<int>(rng_() & 0xff));
        break;
    }
  }

  std::vector<std::string> names_, unknown_;
};

}  // namespace

TEST_CASE("The MessagePack fast path decodes every payload as the full reader does",
          "[codec][fast]") {
  const std::vector<std::string> names = {"LASI", "RASI", "LPSI", "RPSI", "LKNE", "RKNE",
                                          "LTOE", "R.Heel", "with space", "\xc3\xa9paule",
                                          "Subject:left_lateral_epicondyle_long_name_past_32_bytes",
                                          "LASI"};
  const std::vector<std::string> unknown = {"X", "boite:gauche_exterieur", "\xc3\xa9t\xc3\xa9",
                                            std::string("nul\0byte", 8), ""};
  const std::vector<std::string> sensors = {"S0", "S1"};
  MsgpackMaker maker(names, unknown, 2026);
  const Verdicts v = decode_both_ways(maker, names, sensors, 40000);
  CAPTURE(v.accepted, v.refused, v.fast_path_frames);
  CHECK(v.accepted > 15000);
  CHECK(v.refused > 5000);
  CHECK(v.fast_path_frames > 10000);
}

TEST_CASE("The encoder's own MessagePack frames take the fast path", "[codec][fast]") {
  const std::vector<std::string> names = {"A", "B", "C"};
  MarkerDecoder d(names, 1e-3, 1 << 20);
  MarkerFrame f = d.make_frame();
  std::string payload, error;
  const std::vector<Eigen::Vector3d> p_m = {{0.1, 0.2, 0.3}, {1, 2, 3}, {-0.5, 0.25, 1e-4}};
  const std::vector<std::uint8_t> visible = {1, 0, 1};
  const std::vector<float> confidence = {0.9f, 1.0f, 0.2f};
  const double time_s = 0.5, stamp_us = 1.7e15;
  for (const std::string_view units : {"m", "mm"}) {
    encode_marker_frame(7, &time_s, names, p_m, visible, units, PayloadEncoding::msgpack, payload,
                        &stamp_us, nullptr, confidence);
    const std::uint64_t before = d.fast_path_frames();
    REQUIRE(d.decode(bytes(payload), f, error));
    CHECK(d.fast_path_frames() == before + 1);
    CHECK(f.frame == 7);
    CHECK(f.time_s == time_s);
    CHECK(f.stamp_us == stamp_us);
    CHECK(f.visible == visible);
    CHECK(f.confidence_count == 2);
    CHECK(f.confidence[2] == Approx(0.2f));
    CHECK((f.p_world_m[2] - p_m[2]).norm() < 1e-12);
  }
}

TEST_CASE("The MessagePack fast path reads each width to its known value", "[codec][fast]") {
  const std::vector<std::string> names = {"A", "B"};
  MarkerDecoder d(names, 1e-3, 1 << 20);
  MarkerFrame f = d.make_frame();
  std::string error;
  // {"frame": uint16 513, "units": str8 "m", "markers": map16 {"A": [int8 -2, float32 0.5,
  //  uint8 20, float64 2.0 (confidence, clamped to 1)], "B": nil}}
  const std::string p(
      "\x83"
      "\xa5" "frame" "\xcd\x02\x01"
      "\xa5" "units" "\xd9\x01" "m"
      "\xa7" "markers" "\xde\x00\x02"
      "\xa1" "A" "\x94" "\xd0\xfe" "\xca\x3f\x00\x00\x00" "\xcc\x14" "\xcb\x40\x00\x00\x00\x00\x00\x00\x00"
      "\xa1" "B" "\xc0",
      1 + 6 + 3 + 6 + 3 + 8 + 3 + 2 + 1 + 2 + 5 + 2 + 9 + 2 + 1);
  REQUIRE(d.decode(bytes(p), f, error));
  CHECK(d.fast_path_frames() == 1);
  CHECK(f.frame == 513);
  CHECK(f.visible == std::vector<std::uint8_t>{1, 0});
  CHECK(f.p_world_m[0] == Eigen::Vector3d(-2.0, 0.5, 20.0));  // "m": no scaling
  CHECK(f.confidence[0] == 1.0f);
  CHECK(f.confidence_count == 1);
  CHECK(f.known_count == 2);
}
