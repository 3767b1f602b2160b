// The register table: consistent, encodes at the edge as documented, and the committed
// docs/registers.md is exactly what the table generates.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "maglead/registers/registers.hpp"

using namespace maglead::registers;

TEST(Registers, NamesAreUniqueAndAddressesDoNotOverlap) {
  std::set<std::string_view> names;
  std::set<std::pair<int, int>> words;  // (space, address); input and holding share one space
  for (const auto& r : table()) {
    EXPECT_TRUE(names.insert(r.name).second) << r.name;
    const int space = r.table == Table::coil ? 0 : r.table == Table::discrete_input ? 1 : 2;
    for (int w = 0; w < word_count(r.type); ++w)
      EXPECT_TRUE(words.insert({space, r.address + w}).second)
          << r.name << " overlaps at " << r.address + w;
    EXPECT_LE(r.min, r.max) << r.name;
    EXPECT_GT(r.scale, 0.0) << r.name;
    EXPECT_FALSE(r.description.empty()) << r.name;
    if (r.table == Table::coil || r.table == Table::discrete_input) {
      EXPECT_EQ(r.type, Type::bit) << r.name;
    }
    if (r.access == Access::read_write) {
      EXPECT_TRUE(r.table == Table::holding_register || r.table == Table::coil) << r.name;
    }
  }
}

TEST(Registers, Every32BitScaledValueHasAFloatTwin) {
  for (const auto& r : table()) {
    if (r.type != Type::i32) continue;
    std::string base(r.name);
    for (const char* unit : {"_um_s2", "_um_s", "_um", "_urad", "_mn"}) {  // nut_pos_um -> nut_pos
      const std::string u(unit);
      if (base.size() > u.size() && base.compare(base.size() - u.size(), u.size(), u) == 0) {
        base.resize(base.size() - u.size());
        break;
      }
    }
    bool found = false;
    for (const auto& f : table())
      if (f.type == Type::f32 && std::string(f.name).rfind(base + "_", 0) == 0 &&
          f.table == r.table)
        found = true;
    EXPECT_TRUE(found) << r.name << " has no float32 twin";
  }
}

TEST(Registers, BitEnumsMatchTheTable) {
  EXPECT_EQ(find("enable")->address, kEnable);
  EXPECT_EQ(find("execute")->address, kExecute);
  EXPECT_EQ(find("step_out")->address, kStepOut);
  EXPECT_EQ(find("twin_healthy")->address, kTwinHealthy);
  EXPECT_EQ(find("stroke_limit")->address, kStrokeLimit);
  EXPECT_EQ(find("control_word")->max, kControlWordMask);
  EXPECT_EQ(find("no_such_register"), nullptr);
}

TEST(Registers, LookupByAddressFindsWordIndex) {
  int w = -1;
  const Register* r = at(Table::input_register, 21, &w);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->name, "nut_pos_um");
  EXPECT_EQ(w, 1);
  EXPECT_EQ(at(Table::input_register, 95), nullptr);  // reserved
  EXPECT_EQ(at(Table::holding_register, 21), nullptr);
}

TEST(Registers, WordOrderIsHighWordFirst) {
  std::uint16_t words[2];
  encode(*find("word_order_probe_u32"), kWordOrderProbeU32, words);
  EXPECT_EQ(words[0], 0x1234);
  EXPECT_EQ(words[1], 0x5678);
  encode(*find("word_order_probe_f32"), kWordOrderProbeF32, words);
  EXPECT_EQ(words[0], 0x449A);
  EXPECT_EQ(words[1], 0x522B);
}

TEST(Registers, ScaledIntegersRoundTripAndSaturate) {
  const Register& pos = *find("nut_pos_um");
  std::uint16_t w[2];
  encode(pos, -0.0123456, w);
  EXPECT_NEAR(decode(pos, w), -0.012346, 1e-12);
  encode(pos, 1e6, w);  // far beyond i32 µm: saturates, does not wrap
  EXPECT_NEAR(decode(pos, w), 2147483647e-6, 1e-9);
  encode(pos, std::nan(""), w);
  EXPECT_EQ(decode(pos, w), 0.0);
  const Register& force = *find("force_setpoint_n_f32");
  encode(force, 12.5, w);
  EXPECT_EQ(decode(force, w), 12.5);
  const Register& wd = *find("watchdog_ms");
  encode(wd, 0.25, w);
  EXPECT_EQ(w[0], 250);
}

TEST(Registers, RangeCheckRefusesOutsideAndNonFinite) {
  const Register& pos = *find("position_setpoint_um");
  EXPECT_TRUE(in_range(pos, 0.04));
  EXPECT_FALSE(in_range(pos, 0.040001));
  EXPECT_FALSE(in_range(pos, -1e-6));
  EXPECT_FALSE(in_range(*find("force_setpoint_n_f32"), std::numeric_limits<double>::infinity()));
  EXPECT_TRUE(in_range(*find("position_setpoint_m_f32"),
                       static_cast<float>(0.04)));  // float rounding of the limit
}

// The documented limits are accepted as typed (1e-05 m/s) and as the server decodes them after
// encode (10 × 1e-6 = 9.999999999999999e-06 m/s, refused before); one raw unit beyond is not.
TEST(Registers, EveryWritableLimitIsInRangeAsTypedAndAsDecoded) {
  for (const auto& r : table()) {
    if (r.access != Access::read_write || r.type == Type::bit) continue;
    for (const double limit : {r.min, r.max}) {
      std::uint16_t w[2] = {0, 0};
      encode(r, limit, w);
      EXPECT_TRUE(in_range(r, limit)) << r.name << " " << limit;
      EXPECT_TRUE(in_range(r, decode(r, w))) << r.name << " decoded " << decode(r, w);
    }
    if (r.type == Type::f32) continue;
    EXPECT_FALSE(in_range(r, r.min - r.scale)) << r.name;
    EXPECT_FALSE(in_range(r, r.max + r.scale)) << r.name;
  }
  const Register& speed = *find("velocity_limit_um_s");
  EXPECT_TRUE(in_range(speed, 10 * 1e-6));  // 10um/s, as the tool parses it
  EXPECT_TRUE(in_range(speed, 9.6e-6));     // rounds to 10 µm/s, the limit
  EXPECT_FALSE(in_range(speed, 9.4e-6));    // rounds to 9 µm/s
}

TEST(Registers, CsvAndJsonListEveryEntry) {
  const std::string csv = to_csv();
  const auto lines = std::count(csv.begin(), csv.end(), '\n');
  EXPECT_EQ(static_cast<std::size_t>(lines), table().size() + 1);
  const auto j = nlohmann::json::parse(to_json());
  EXPECT_EQ(j["registers"].size(), table().size());
  EXPECT_EQ(j["registers"][0]["name"], "device_type");
}

// watchdog_ms's range used to read "0 .. 60" (seconds) on a register written in ms.
TEST(Registers, TheDocShowsEachRangeInTheRegistersOwnUnit) {
  const std::string md = to_markdown();
  EXPECT_NE(md.find("| `watchdog_ms` | u16 | 0.001 | s | RW | 0 .. 60000 (0 .. 60 s) |"),
            std::string::npos);
  for (const auto& r : table()) {
    if (r.access != Access::read_write || r.scale == 1.0) continue;
    char raw[64];
    std::snprintf(raw, sizeof raw, "| %.10g .. %.10g (", std::round(r.min / r.scale),
                  std::round(r.max / r.scale));
    const auto row = md.find("| `" + std::string(r.name) + "` |");
    ASSERT_NE(row, std::string::npos) << r.name;
    EXPECT_NE(md.substr(row, md.find('\n', row) - row).find(raw), std::string::npos) << r.name;
  }
}

TEST(Registers, CommittedDocMatchesTheTable) {
  std::ifstream in(MAGLEAD_REGISTERS_DOC);
  ASSERT_TRUE(in) << "missing " << MAGLEAD_REGISTERS_DOC;
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_TRUE(ss.str() == to_markdown())
      << "docs/registers.md is stale: run `maglead registers --format md > docs/registers.md`";
}
