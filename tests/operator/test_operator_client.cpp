// The client's pure parts: unit parsing, the server-equivalent checks, request blocks.
#include <gtest/gtest.h>

#include "maglead/operator/client.hpp"

namespace op = maglead::op;
namespace reg = maglead::registers;

TEST(OperatorClient, ParsesQuantitiesWithUnits) {
  EXPECT_DOUBLE_EQ(op::parse_quantity("12.5", "N"), 12.5);
  EXPECT_DOUBLE_EQ(op::parse_quantity("12.5N", "N"), 12.5);
  EXPECT_DOUBLE_EQ(op::parse_quantity("-500 mN", "N"), -0.5);
  EXPECT_DOUBLE_EQ(op::parse_quantity("20mm", "m"), 0.02);
  EXPECT_DOUBLE_EQ(op::parse_quantity("5mm/s", "m/s"), 0.005);
  EXPECT_DOUBLE_EQ(op::parse_quantity("250ms", "s"), 0.25);
  EXPECT_DOUBLE_EQ(op::parse_quantity("2min", "s"), 120.0);
  EXPECT_DOUBLE_EQ(op::parse_quantity("1h", "s"), 3600.0);
  try {  // "m" is metres everywhere, so a time in "m" is refused with what to type
    op::parse_quantity("2m", "s");
    ADD_FAILURE() << "2m accepted as a time";
  } catch (const op::ClientError& e) {
    EXPECT_NE(std::string(e.what()).find("'2m' is metres; for minutes type 2min"),
              std::string::npos);
  }
  EXPECT_THROW(op::parse_quantity("20mm", "N"), op::ClientError);  // wrong quantity
  EXPECT_THROW(op::parse_quantity("twelve", "N"), op::ClientError);
  EXPECT_THROW(op::parse_quantity("nan", "N"), op::ClientError);
  try {
    op::parse_quantity("3 furlongs", "m");
    ADD_FAILURE() << "3 furlongs accepted as a length";
  } catch (const op::ClientError& e) {
    EXPECT_EQ(e.kind(), op::ClientError::Kind::refused_locally);
    EXPECT_EQ(e.exit_code(), 2);
    EXPECT_NE(std::string(e.what()).find("mm"), std::string::npos);  // says what is accepted
  }
}

TEST(OperatorClient, ADecimalCommaIsRefusedWithTheNumberToType) {
  try {
    op::parse_quantity("1,5", "N");
    ADD_FAILURE() << "1,5 accepted";
  } catch (const op::ClientError& e) {
    EXPECT_EQ(e.exit_code(), 2);
    EXPECT_NE(std::string(e.what()).find("use a decimal point, not a comma: '1.5'"),
              std::string::npos)
        << e.what();
  }
}

TEST(OperatorClient, ForceCheckMatchesTheServersInverse) {
  op::Limits l;
  l.calibration = maglead::paper_calibration();
  l.calibration_source = "paper";
  const double push = l.actuator.safe_force_fraction * l.calibration.peak_push_n;
  const double pull = l.actuator.safe_force_fraction * l.calibration.peak_pull_n;
  EXPECT_FALSE(op::check_force(l, 0.99 * push));
  EXPECT_FALSE(op::check_force(l, 0.99 * pull));
  ASSERT_TRUE(op::check_force(l, 1.01 * push));
  EXPECT_NE(op::check_force(l, 1.01 * push)->find("safe limit"), std::string::npos);
  EXPECT_TRUE(op::check_force(l, 1.01 * pull));
  // The safe limit first: it is the configured one, well inside the register's ±100 N.
  ASSERT_TRUE(op::check_force(l, 150.0));
  EXPECT_NE(op::check_force(l, 150.0)->find("safe limit"), std::string::npos);
}

TEST(OperatorClient, PositionCheckUsesTheStroke) {
  op::Limits l;
  l.actuator.stroke_min_m = 0.005;
  l.actuator.stroke_max_m = 0.035;
  EXPECT_FALSE(op::check_position(l, 0.02));
  EXPECT_TRUE(op::check_position(l, 0.036));  // inside the register range, outside this stroke
  EXPECT_TRUE(op::check_position(l, 0.041));  // outside the register range
}

TEST(OperatorClient, TheControllersReportedLimitsDecideOverTheConfiguration) {
  op::Limits l;  // this machine's configuration: the defaults, a 0 .. 40 mm stroke
  l.reported = op::ReportedLimits{-20.0, 18.0, 0.005, 0.04};
  EXPECT_FALSE(op::check_force(l, 18.0));  // the limit itself, as read back from its float32
  EXPECT_FALSE(op::check_force(l, -20.0));
  ASSERT_TRUE(op::check_force(l, 18.01));
  EXPECT_NE(op::check_force(l, 18.01)->find("allowed -20 .. 18 N (the controller's limits"),
            std::string::npos);
  EXPECT_TRUE(op::check_force(l, -20.01));
  // 0.04 m typed against its float32 0.0399999991 is at the stroke end, not beyond it.
  EXPECT_FALSE(op::check_position(l, static_cast<double>(0.04f) + 1e-12));
  EXPECT_FALSE(op::check_position(l, 0.04));
  EXPECT_TRUE(op::check_position(l, 0.0401));
  EXPECT_TRUE(
      op::check_position(l, 0.004));  // inside this machine's stroke, outside the controller's
}

TEST(OperatorClient, BlocksCoverEveryRegisterOnceWithoutGaps) {
  for (auto t : {reg::Table::input_register, reg::Table::holding_register}) {
    int words = 0, covered = 0;
    for (const auto& r : reg::table())
      if (r.table == t) words += reg::word_count(r.type);
    for (const auto& b : op::read_blocks(t)) {
      EXPECT_LE(b.count, 125);
      covered += b.count;
      for (std::uint16_t a = b.start; a < b.start + b.count; ++a) {
        int w = -1;
        EXPECT_NE(reg::at(t, a, &w), nullptr) << "gap at " << a;  // a gap would be exception 02
        if (a == b.start) {
          EXPECT_EQ(w, 0) << "block starts inside a 32-bit value at " << a;
        }
      }
    }
    EXPECT_EQ(covered, words);
  }
}

TEST(OperatorClient, SpellsOutCodesAndBits) {
  EXPECT_EQ(op::code_name(reg::alarm_codes(), 1), "step_out");
  EXPECT_EQ(op::code_name(reg::reject_codes(), 3), "force_beyond_safe_limit");
  EXPECT_EQ(op::code_name(reg::alarm_codes(), 99), "unknown (99)");
  const auto bits =
      op::status_bits(static_cast<std::uint16_t>((1u << reg::kEnabled) | (1u << reg::kStepOut)));
  EXPECT_EQ(bits, (std::vector<std::string>{"enabled", "step_out"}));
}

TEST(OperatorClient, ConnectionRefusedIsOneCommunicationError) {
  op::Endpoint ep;
  ep.port = 1;  // privileged and unused: refused at once
  try {
    op::Client c(ep);
    FAIL() << "connected to port 1";
  } catch (const op::ClientError& e) {
    EXPECT_EQ(e.exit_code(), 3);
    EXPECT_NE(std::string(e.what()).find("cannot connect to 127.0.0.1:1"), std::string::npos)
        << e.what();
  }
}

TEST(OperatorClient, DriveLimitAdviceTypesTheForceWithItsUnit) {
  const std::string said = op::drive_limit_reached_text(28.27, 38.4);
  EXPECT_NE(said.find("safe limit 38.4 N"), std::string::npos) << said;
  EXPECT_NE(said.find("'maglead set force 28.2N'"), std::string::npos) << said;  // as typed
}
