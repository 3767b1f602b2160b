// config/drive.toml: the shipped file, and the refusals of a bad one at its line.
#include <gtest/gtest.h>

#include <fstream>
#include <stdexcept>
#include <string>

#include "maglead/canopen/cia402_hardware.hpp"
#include "maglead/settings/settings.hpp"

namespace maglead::canopen {
namespace {

std::string write_file(const std::string& name, const std::string& text) {
  std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

std::string refusal(const std::string& text) {
  try {
    load_drive_config(write_file("drive_bad.toml", text), DriveConfig{});
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "accepted";
}

TEST(DriveConfigFile, TheShippedFileIsThePaperActuatorsDrive) {
  DriveConfig base;
  base.counts_per_motor_turn = 1;  // every key of the file overrides
  base.second_encoder_m_per_count = 1;
  const DriveConfig c = load_drive_config(MAGLEAD_CONFIG_DIR "/drive.toml", base);
  const ActuatorParams paper;
  EXPECT_EQ(c.node_id, 1);
  EXPECT_EQ(c.bitrate_bit_s, 1'000'000U);
  EXPECT_EQ(c.counts_per_motor_turn, paper.motor_counts_per_rev);
  EXPECT_EQ(c.second_encoder_index, 0x60E4);
  EXPECT_EQ(c.second_encoder_sub, 1);
  EXPECT_NEAR(c.second_encoder_m_per_count, paper.linear_count_m, 1e-8);  // 3 digits in the file
  EXPECT_EQ(c.heartbeat_producer_s, 0.1);
  EXPECT_EQ(c.heartbeat_timeout_s, 0.3);
  EXPECT_EQ(c.sdo_timeout_s, 0.05);
  EXPECT_EQ(c.sdo_attempts, 3);
}

// The keys the start-up's timeout advice names are ones the file takes.
TEST(DriveConfigFile, TheSdoRetriesTheAdviceNamesAreSettable) {
  const DriveConfig c = load_drive_config(
      write_file("drive_sdo.toml", "[drive]\nsdo_timeout_s = 0.2\nsdo_attempts = 8\n"),
      DriveConfig{});
  EXPECT_EQ(c.sdo_timeout_s, 0.2);
  EXPECT_EQ(c.sdo_attempts, 8);
  EXPECT_NE(refusal("[drive]\nsdo_attempts = 0\n").find("outside 1 .. 100"), std::string::npos);
}

TEST(DriveConfigFile, AbsentKeysKeepTheBase) {
  DriveConfig base;
  base.node_id = 9;
  const DriveConfig c = load_drive_config(write_file("drive_min.toml", "[drive]\n"), base);
  EXPECT_EQ(c.node_id, 9);
}

TEST(DriveConfigFile, ABadFileIsRefusedAtItsLineWithTheKey) {
  EXPECT_NE(refusal("[drive]\nnode_id = 300\n")
                .find("drive_bad.toml:2:11: drive.node_id: 300 is outside 1 .. 127"),
            std::string::npos);
  EXPECT_NE(refusal("[drive]\nnode_id = 1.5\n").find("must be a whole number"), std::string::npos);
  EXPECT_NE(refusal("[drive]\nnode = 1\n").find("unknown key 'node'"), std::string::npos);
  EXPECT_NE(refusal("[drives]\n").find("unknown key 'drives'"), std::string::npos);
  EXPECT_NE(refusal("# nothing\n").find("missing [drive] table"), std::string::npos);
  EXPECT_NE(refusal("[drive]\nsecond_encoder_index = \"0x60E4\"\n").find("must be a number"),
            std::string::npos);
  // Across keys: 1 ms cycles do not fit 500 kbit/s; a timeout under 1.5 heartbeats.
  EXPECT_NE(refusal("[drive]\nbitrate_bit_s = 500000\n").find("80 % of the bus"),
            std::string::npos);
  EXPECT_NE(refusal("[drive]\nheartbeat_timeout_s = 0.12\n").find("heartbeat_timeout_s"),
            std::string::npos);
}

}  // namespace
}  // namespace maglead::canopen
