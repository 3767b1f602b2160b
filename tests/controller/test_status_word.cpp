// The status word as a pure function: each fact sets exactly the bit whose discrete input the
// register table names for it, and nothing else.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "maglead/controller/status_word.hpp"
#include "maglead/registers/registers.hpp"

namespace {

using maglead::controller::pack_status_word;
using maglead::controller::StatusFacts;
using maglead::registers::DriveState;
namespace reg = maglead::registers;

std::uint16_t bit_named(const std::string& name) {
  const auto* r = reg::find(name);
  EXPECT_NE(r, nullptr) << name;
  EXPECT_EQ(r->table, reg::Table::discrete_input) << name;
  return static_cast<std::uint16_t>(1u << r->address);
}

TEST(StatusWord, NothingSetWhenDisabledAndIdle) { EXPECT_EQ(pack_status_word({}), 0); }

TEST(StatusWord, EachDriveStateItsOwnBit) {
  EXPECT_EQ(pack_status_word({.state = DriveState::ready}), bit_named("ready"));
  EXPECT_EQ(pack_status_word({.state = DriveState::enabled}), bit_named("enabled"));
  EXPECT_EQ(pack_status_word({.state = DriveState::fault}), bit_named("fault"));
}

TEST(StatusWord, EachFactItsNamedBit) {
  struct Case {
    bool StatusFacts::*fact;
    const char* bit;
  };
  const std::vector<Case> cases = {
      {&StatusFacts::moving, "moving"},
      {&StatusFacts::in_position, "in_position"},
      {&StatusFacts::force_reached, "force_reached"},
      {&StatusFacts::stepped_out, "step_out"},
      {&StatusFacts::drift_warning, "drift_warning"},
      {&StatusFacts::watchdog_expired, "watchdog_expired"},
      {&StatusFacts::twin_healthy, "twin_healthy"},
      {&StatusFacts::step_out_warning, "step_out_warning"},
      {&StatusFacts::stopped, "stopped"},
      {&StatusFacts::at_stroke_limit, "stroke_limit"},
      {&StatusFacts::twin_lagging, "twin_lagging"},
      {&StatusFacts::force_limited, "force_limited"},
  };
  std::uint16_t all = 0;
  for (const auto& c : cases) {
    StatusFacts f;
    f.*(c.fact) = true;
    EXPECT_EQ(pack_status_word(f), bit_named(c.bit)) << c.bit;
    EXPECT_EQ(all & bit_named(c.bit), 0) << c.bit << " shares a bit";
    all = static_cast<std::uint16_t>(all | bit_named(c.bit));
  }
  // "owned" is the Modbus layer's (per connection), never the cycle's.
  StatusFacts every{.state = DriveState::enabled};
  for (const auto& c : cases) every.*(c.fact) = true;
  EXPECT_EQ(pack_status_word(every) & bit_named("owned"), 0);
  EXPECT_EQ(pack_status_word(every), all | bit_named("enabled"));
}

}  // namespace
