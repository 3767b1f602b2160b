// `maglead serve --backend cia402` end to end: the whole product through the CANopen path with
// the simulated drive (--can sim), and the refusals a user meets without a CAN interface.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace {

struct Served {
  int exit_code;
  std::string out;  // stdout and stderr together
};

Served serve(const std::string& args) {
  const std::string cmd = std::string(MAGLEAD_BIN) + " serve " + args + " --config " +
                          MAGLEAD_CONFIG_DIR + " --port 0 --no-twin 2>&1";
  Served r{0, ""};
  FILE* p = popen(cmd.c_str(), "r");
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), buf.size(), p) != nullptr) r.out += buf.data();
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

TEST(Cia402Cli, ServesThroughTheSimulatedDrive) {
  const Served r = serve("--backend cia402 --can sim --sim-can-drop 0.01 --duration 2s");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("CiA 402 drive, node 1 on the simulated bus: vendor 0x000000FB"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("40 % of the bus at 1000000 bit/s"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("through a simulated CiA 402 drive"), std::string::npos) << r.out;
  // The loop ran for most of its 2 s at 1 kHz (a loaded machine may overrun a few cycles).
  const auto at = r.out.find("stopped after ");
  ASSERT_NE(at, std::string::npos) << r.out;
  EXPECT_GT(std::strtoll(r.out.c_str() + at + 14, nullptr, 10), 1000) << r.out;
}

TEST(Cia402Cli, AMissingInterfaceExitsTwoNamingItAndHowToBringOneUp) {
  const Served r = serve("--backend cia402 --can mlnocan7 --duration 1s");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("\"mlnocan7\" does not exist"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ip link set mlnocan7 up type can bitrate 1000000"), std::string::npos)
      << r.out;
}

TEST(Cia402Cli, CanOptionsWithoutTheirBackendAreRefused) {
  EXPECT_EQ(serve("--can can0 --duration 1s").exit_code, 2);
  // sim too: without the backend it would run the plain simulated actuator, not CANopen.
  const auto sim = serve("--can sim --duration 1s");
  EXPECT_EQ(sim.exit_code, 2);
  EXPECT_NE(sim.out.find("type --backend cia402 --can sim"), std::string::npos) << sim.out;
  EXPECT_EQ(serve("--backend cia402 --can can0 --sim-can-drop 0.01 --duration 1s").exit_code, 2);
  EXPECT_EQ(serve("--backend nosuch --duration 1s").exit_code, 2);
  // An empty name is no interface: refused, not taken as the simulated drive.
  const auto empty = serve("--backend cia402 --can '' --duration 1s");
  EXPECT_EQ(empty.exit_code, 2);
  EXPECT_NE(empty.out.find("--can: an interface name (e.g. can0) or sim"), std::string::npos)
      << empty.out;
}

}  // namespace

// A start-up on a bus that loses every tenth frame fails on an SDO that timed out on every
// attempt; the error says so and which drive.toml keys set the attempts.
TEST(Cia402Cli, AStartUpSDOLostOnEveryAttemptSaysWhatToCheck) {
  const Served r = serve("--backend cia402 --can sim --sim-can-drop 0.1 --duration 1s");
  EXPECT_NE(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("timed out (no answer within 0.05 s on any of 3 attempts, sdo_timeout_s "
                       "and sdo_attempts in drive.toml"),
            std::string::npos)
      << r.out;
}
