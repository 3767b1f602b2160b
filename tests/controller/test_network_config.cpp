// config/network.toml: the shipped file loads, values land where they belong, and bad files
// are refused with the file and key named.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>

#include "maglead/modbus/network_config.hpp"
#include "maglead/settings/settings.hpp"

using namespace maglead::controller;
using namespace maglead::modbus;

namespace {

std::string write_temp(const std::string& name, const std::string& text) {
  std::string path = std::string(MAGLEAD_TEST_TMP) + "/" + name;
  std::ofstream(path) << text;
  return path;
}

std::string error_of(const std::string& path) {
  try {
    load_network_config(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(NetworkConfig, ShippedFileLoadsWithLoopbackDefaults) {
  const NetworkConfig c = load_network_config(MAGLEAD_CONFIG_DIR "/network.toml");
  EXPECT_EQ(c.tcp.bind_address, "127.0.0.1");
  EXPECT_EQ(c.tcp.port, 1502);
  EXPECT_TRUE(c.tcp_enabled);
  EXPECT_TRUE(c.rtu.device.empty());
  EXPECT_EQ(c.rtu.parity, 'E');
  EXPECT_EQ(c.rtu.baud, 19200);
  EXPECT_FALSE(c.read_only);
  EXPECT_EQ(c.watchdog_s, 0.0);
}

TEST(NetworkConfig, ValuesAreRead) {
  const auto path = write_temp(
      "net_ok.toml",
      "[tcp]\nport = 5020\nallow = [\"10.0.0.0/8\", \"127.0.0.1\"]\nmax_connections = 4\n"
      "[rtu]\ndevice = \"/dev/ttyS1\"\nparity = \"N\"\nstop_bits = 2\nunit_id = 17\n"
      "[server]\nread_only = true\nwatchdog_ms = 250\n");
  const NetworkConfig c = load_network_config(path);
  EXPECT_EQ(c.tcp.port, 5020);
  ASSERT_EQ(c.tcp.allow.size(), 2u);
  EXPECT_EQ(c.tcp.max_connections, 4);
  EXPECT_EQ(c.rtu.device, "/dev/ttyS1");
  EXPECT_EQ(c.rtu.parity, 'N');
  EXPECT_EQ(c.rtu.stop_bits, 2);
  EXPECT_EQ(c.rtu.unit_id, 17);
  EXPECT_TRUE(c.read_only);
  EXPECT_DOUBLE_EQ(c.watchdog_s, 0.25);
}

TEST(NetworkConfig, BadFilesNameTheKey) {
  EXPECT_NE(error_of(write_temp("n1.toml", "[tcp]\nprot = 1\n")).find("[tcp] unknown key 'prot'"),
            std::string::npos);
  EXPECT_NE(error_of(write_temp("n2.toml", "[tcp]\nport = 70000\n")).find("tcp.port"),
            std::string::npos);
  EXPECT_NE(error_of(write_temp("n3.toml", "[tcp]\nport = \"x\"\n")).find("must be a number"),
            std::string::npos);
  EXPECT_NE(error_of(write_temp("n4.toml", "[rtu]\nparity = \"X\"\n")).find("rtu.parity"),
            std::string::npos);
  EXPECT_NE(error_of(write_temp("n5.toml", "[tcp]\nallow = [\"300.1.1.1\"]\n")).find("tcp.allow"),
            std::string::npos);
  EXPECT_NE(error_of(write_temp("n6.toml", "[modbus]\n")).find("unknown section"),
            std::string::npos);
  EXPECT_NE(error_of(write_temp("n7.toml", "[tcp\n")).find("n7.toml"), std::string::npos);
  EXPECT_NE(error_of(write_temp("n8.toml", "[rtu]\nunit_id = 1.5\n")).find("whole number"),
            std::string::npos);
  // Every error points at FILE:LINE:COLUMN (the value, the key's line, or the syntax error).
  EXPECT_NE(error_of(write_temp("n2.toml", "[tcp]\nport = 70000\n")).find("n2.toml:2:8: tcp.port"),
            std::string::npos);
  EXPECT_NE(error_of(write_temp("n1.toml", "[tcp]\nprot = 1\n"))
                .find("n1.toml:2:8: [tcp] unknown key 'prot'"),
            std::string::npos);
  EXPECT_NE(error_of(write_temp("n7.toml", "[tcp\n")).find("n7.toml:1:"), std::string::npos);
}

TEST(NetworkConfig, AllowListParsesCidr) {
  EXPECT_EQ(parse_ipv4_cidr("10.1.2.3/8"), std::make_pair(0x0A000000u, 0xFF000000u));
  EXPECT_EQ(parse_ipv4_cidr("127.0.0.1"), std::make_pair(0x7F000001u, 0xFFFFFFFFu));
  EXPECT_EQ(parse_ipv4_cidr("0.0.0.0/0").second, 0u);
  EXPECT_THROW(parse_ipv4_cidr("10.0.0.0/33"), std::invalid_argument);
  EXPECT_THROW(parse_ipv4_cidr("localhost"), std::invalid_argument);
}

TEST(NetworkConfig, RuntimeRealtimePolicy) {
  EXPECT_EQ(load_network_config(MAGLEAD_CONFIG_DIR "/network.toml").realtime,
            RealtimePolicy::attempt);
  EXPECT_EQ(load_network_config(write_temp("rt_req.toml", "[runtime]\nrealtime = \"require\"\n"))
                .realtime,
            RealtimePolicy::require);
  EXPECT_EQ(
      load_network_config(write_temp("rt_off.toml", "[runtime]\nrealtime = \"off\"\n")).realtime,
      RealtimePolicy::off);
  const std::string e = error_of(write_temp("rt_bad.toml", "[runtime]\nrealtime = \"yes\"\n"));
  EXPECT_NE(e.find("runtime.realtime"), std::string::npos) << e;
  EXPECT_NE(e.find("off, try, require"), std::string::npos) << e;
}
