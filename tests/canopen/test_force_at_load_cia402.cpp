// The force at the load through the CiA 402 path (issue 45): the force-at-load check of issue 22
// with the controller on the backend "cia402" and its simulated drive on the virtual bus (what
// `maglead serve --backend cia402 --can sim` runs), clean and with 1 % of the frames lost. Same
// setpoints, same tolerances as the direct path. The test reads the load cell of the simulated
// actuator inside the drive; the controller is given NaN for it, as on a real drive.
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>

#include "controller/force_at_load.hpp"
#include "maglead/canopen/cia402_hardware.hpp"

namespace maglead::testing {
namespace {

/// What the drive's path went through, kept when the rig is gone: the proof that the sequence
/// ran through the CANopen master with its drive enabled, and lost frames where asked.
struct PathReport {
  std::uint64_t cycles = 0, missed_tpdo = 0;
  canopen::DriveState final_state = canopen::DriveState::unknown;
};

class DrivePath final : public PlantPath {
 public:
  DrivePath(const PlantParams& params, std::uint64_t seed, double nut_m, double drop_fraction,
            PathReport& report)
      : hw_(params.actuator, options(drop_fraction),
            std::make_unique<SimulatedActuator>(params, seed, nut_m)),
        report_(report) {}
  ~DrivePath() override {
    report_.cycles = hw_.master().counters().cycles;
    report_.missed_tpdo = hw_.master().counters().missed_tpdo;
    report_.final_state = hw_.master().feedback().state;
  }
  DrivePath(const DrivePath&) = delete;
  DrivePath& operator=(const DrivePath&) = delete;
  ActuatorHardware& hardware() override { return hw_; }
  SimulatedActuator& plant() override { return *hw_.simulated_plant(); }

 private:
  static canopen::Cia402BackendOptions options(double drop_fraction) {
    canopen::Cia402BackendOptions o;
    o.sim_drop_fraction = drop_fraction;
    o.sim_seed = 11;
    return o;
  }
  canopen::Cia402Hardware hw_;
  PathReport& report_;
};

/// The sequence on `lc` through the drive, and what the path saw.
void through_the_drive(const LoadCase& lc, double drop_fraction) {
  PathReport report;
  const PlantPathFactory path = [&](const PlantParams& params, std::uint64_t seed, double nut_m) {
    return std::make_unique<DrivePath>(params, seed, nut_m, drop_fraction, report);
  };
  expect_on_the_load(run_sequence(lc, {}, ServedModel{}, path));
  std::printf("%-10s %llu cycles, %llu TPDOs missed, drive %s at the end\n", lc.name,
              static_cast<unsigned long long>(report.cycles),
              static_cast<unsigned long long>(report.missed_tpdo),
              canopen::drive_state_text(report.final_state));
  EXPECT_GT(report.cycles, 30000U);
  EXPECT_EQ(report.final_state, canopen::DriveState::operation_enabled);
  if (drop_fraction > 0.0) {
    EXPECT_GT(report.missed_tpdo, 0U);
  } else {
    EXPECT_EQ(report.missed_tpdo, 0U);
  }
}

TEST(ForceAtLoadCia402, Spring2000) { through_the_drive({"cia 2kN/m", 2000}, 0.0); }
TEST(ForceAtLoadCia402, SoftSpring600) { through_the_drive({"cia 600", 600}, 0.0); }
TEST(ForceAtLoadCia402, StiffSpring10000) { through_the_drive({"cia 10kN/m", 10000}, 0.0); }
TEST(ForceAtLoadCia402, HandThatSways) { through_the_drive({"cia hand", 1500, true}, 0.0); }
TEST(ForceAtLoadCia402, Spring2000OnePercentLost) { through_the_drive({"cia 2k 1%", 2000}, 0.01); }
TEST(ForceAtLoadCia402, SoftSpring600OnePercentLost) {
  through_the_drive({"cia 600 1%", 600}, 0.01);
}
TEST(ForceAtLoadCia402, StiffSpring10000OnePercentLost) {
  through_the_drive({"cia 10k 1%", 10000}, 0.01);
}
TEST(ForceAtLoadCia402, HandThatSwaysOnePercentLost) {
  through_the_drive({"cia hand 1%", 1500, true}, 0.01);
}

}  // namespace
}  // namespace maglead::testing
