// The 1 kHz cycle allocates nothing: global operator new/delete are replaced in this test binary
// (counting_new.cpp) and count while armed. Armed from the first cycle on, over thousands of cycles
// of the controller, the simulated plant, the digital twin (runtime::TwinRunner: the loop's push
// into its queue and read of its results, and, drained on this thread between cycles, CVODE with
// its look-ahead and the publication of results) and the Modbus snapshot exchange (requests through
// ModbusCore, which posts commands to the loop's queue and reads its seqlock), through enable,
// position moves, force mode, a fault and its reset. One allocation fails the test. Own executable:
// the replacement is process-wide.
#include <gtest/gtest.h>

#include <cstdint>
#include <new>

#include "counting_new.hpp"
#include "maglead/controller/controller.hpp"
#include "maglead/modbus/modbus_core.hpp"
#include "maglead/plant/simulated_actuator.hpp"
#include "maglead/runtime/twin_runner.hpp"
#include "maglead/settings/settings.hpp"
#include "maglead/twin/monitor.hpp"

using namespace maglead;
using namespace maglead::controller;
using namespace maglead::modbus;
namespace reg = maglead::registers;

namespace {

/// The loop as `maglead serve` wires it, with a Modbus client speaking through ModbusCore.
struct Rig {
  SimulatedActuator plant{paper_like_plant(), 11, 0.02};
  ControllerConfig cfg;
  std::unique_ptr<Controller> ctl;
  std::unique_ptr<runtime::TwinRunner> twin;
  std::unique_ptr<ModbusCore> core;
  double t_s = 0.0;
  // Request buffers: built before arming, the exchange itself must not allocate either.
  std::uint8_t out[ModbusCore::kMaxPdu] = {};

  explicit Rig(bool with_twin = true, bool with_terms = false) {
    LoadSetting load;
    load.kind = LoadSetting::Kind::spring_to_wall;
    load.stiffness_n_per_m = 2000.0;
    load.damping_n_s_per_m = 5.0;
    load.anchor_pos_m = 0.02;
    plant.set_load(load);
    ctl = std::make_unique<Controller>(cfg, plant);
    if (with_twin) {
      twin::TwinMonitorConfig tc = twin::load_monitor_config(MAGLEAD_CONFIG_DIR);
      tc.actuator = cfg.actuator;
      tc.calibration = cfg.calibration;
      tc.integrator.max_step_s = 1.0 / cfg.actuator.sample_rate_hz;
      if (with_terms) {
        // A corrected model as maglead analyze writes it: terms looked up by name every cycle,
        // some names longer than a small-string buffer.
        tc.model.terms.push_back(
            {"stribeck_friction",
             true,
             "",
             {{"breakaway_n", 9.0}, {"coulomb_n", 7.5}, {"stribeck_velocity_m_s", 0.003}}});
        tc.model.terms.push_back(
            {"asymmetric_friction",
             true,
             "",
             {{"coulomb_pos_n", 8.0}, {"coulomb_neg_n", 7.0}, {"viscous_pos_n_s_per_m", 3.0}}});
        tc.model.terms.push_back(
            {"angle_ripple", true, "", {{"relative_amplitude", 0.02}, {"phase_rad", 0.5}}});
        tc.model.terms.push_back({"load_cell_delay", true, "", {{"delay_s", 0.002}}});
        tc.model.terms.push_back({"backlash", true, "", {{"backlash_rad", 0.01}}});
      }
      twin = std::make_unique<runtime::TwinRunner>(tc);
      ctl->attach_twin(twin.get());
    }
    core = std::make_unique<ModbusCore>(*ctl, ServerOptions{false, "test"});
  }
  // The twin's work runs here, on this thread, so that the counter sees it deterministically; in
  // service the twin thread does the same drain().
  void cycle() {
    ctl->step(t_s += 1e-3);
    if (twin) twin->drain();
  }
  std::size_t request(const std::uint8_t* pdu, std::size_t len) {
    return core->handle(ClientInfo{1, 0x7F000001, false}, pdu, len, out);
  }
  // FC16 of one or two words at `address`.
  void write(std::uint16_t address, std::uint16_t w0) {
    const std::uint8_t pdu[] = {16, hi(address), lo(address), 0, 1, 2, hi(w0), lo(w0)};
    request(pdu, sizeof pdu);
  }
  void write32(std::uint16_t address, std::int32_t v) {
    const auto u = static_cast<std::uint32_t>(v);
    const auto w0 = static_cast<std::uint16_t>(u >> 16), w1 = static_cast<std::uint16_t>(u);
    const std::uint8_t pdu[] = {16, hi(address), lo(address), 0,      2,
                                4,  hi(w0),      lo(w0),      hi(w1), lo(w1)};
    request(pdu, sizeof pdu);
  }
  // What a polling client reads: the three blocks the register doc recommends.
  void poll() {
    static constexpr std::uint8_t status[] = {4, 0, 0, 0, 56};
    static constexpr std::uint8_t twin_block[] = {4, 0, 100, 0, 28};
    static constexpr std::uint8_t holding[] = {3, 0x03, 0xE8, 0, 20};
    request(status, sizeof status);
    request(twin_block, sizeof twin_block);
    request(holding, sizeof holding);
  }
  static std::uint8_t hi(std::uint16_t v) { return static_cast<std::uint8_t>(v >> 8); }
  static std::uint8_t lo(std::uint16_t v) { return static_cast<std::uint8_t>(v); }
};

constexpr std::uint16_t bit(int b) { return static_cast<std::uint16_t>(1u << b); }

}  // namespace

// The counter itself: an allocation made while armed is seen (a counter that sees nothing
// would pass every test below).
TEST(NoAllocation, CounterSeesAnAllocation) {
  test_support::AllocationCount armed;
  void* volatile p = ::operator new(24);
  ::operator delete(p);
  EXPECT_EQ(armed.count(), 1u);
}

// A twin hook that allocates inside step(): the cycle test's harness must catch it.
TEST(NoAllocation, AnAllocationInsideTheCycleIsCaught) {
  struct AllocatingTwin final : TwinHook {
    void step(const TwinSample&, TwinReport& out) noexcept override {
      auto* p = new (std::nothrow) double(1.0);
      out.pred_force_n = *p;
      delete p;
    }
  } twin;
  Rig rig(false);
  rig.ctl->attach_twin(&twin);
  test_support::AllocationCount armed;
  for (int i = 0; i < 10; ++i) rig.cycle();
  EXPECT_GE(armed.count(), 10u);  // one per cycle from the hook (more if something else allocates)
}

TEST(NoAllocation, ThousandsOfCyclesWithTwinAndModbusAllocateNothing) {
  Rig rig;
  const std::uint16_t cw = reg::find("control_word")->address;
  const std::uint16_t mode = reg::find("mode_command")->address;
  const std::uint16_t heartbeat = reg::find("heartbeat")->address;
  const std::uint16_t watchdog = reg::find("watchdog_ms")->address;
  const std::uint16_t pos = reg::find("position_setpoint_um")->address;
  const std::uint16_t force = reg::find("force_setpoint_mn")->address;
  const auto pos_mode = static_cast<std::uint16_t>(reg::Mode::position);
  const auto force_mode = static_cast<std::uint16_t>(reg::Mode::force);

  std::uint64_t first_cycle = 0;  // the first cycle that allocated (0: none)
  std::uint16_t seen_states = 0;  // drive states visited (bit per state)
  std::uint16_t max_twin_healthy = 0;
  bool lagged = false;  // drained every cycle, the twin is never behind
  test_support::AllocationCount armed;
  constexpr int kCycles = 8000;
  for (int i = 1; i <= kCycles; ++i) {
    const std::uint64_t before = armed.count();
    // The network side, between cycles: commands into the queue, snapshots out of the seqlock.
    switch (i) {
      case 20:
        rig.write(cw, bit(reg::kEnable));
        break;
      case 30:
        rig.write32(pos, 25'000);
        rig.write(mode, pos_mode);
        break;  // 25 mm
      case 31:
        rig.write(cw, bit(reg::kEnable) | bit(reg::kExecute));
        break;
      case 32:
        rig.write(cw, bit(reg::kEnable));
        break;
      case 1500:
        rig.write32(pos, 15'000);
        break;  // back to 15 mm
      case 1501:
        rig.write(cw, bit(reg::kEnable) | bit(reg::kExecute));
        break;
      case 1502:
        rig.write(cw, bit(reg::kEnable));
        break;
      case 3000:
        rig.write32(force, 10'000);
        rig.write(mode, force_mode);
        break;  // 10 N
      case 3001:
        rig.write(cw, bit(reg::kEnable) | bit(reg::kExecute));
        break;
      case 3002:
        rig.write(cw, bit(reg::kEnable));
        break;
      case 4500:
        rig.write(watchdog, 50);
        break;  // 50 ms without a heartbeat: fault
      case 5500:
        rig.write(watchdog, 0);
        rig.write(cw, bit(reg::kFaultReset));
        break;
      case 5501:
        rig.write(cw, 0);
        break;
      case 5510:
        rig.write(cw, bit(reg::kEnable));
        break;
      case 5520:
        rig.write32(pos, 22'000);
        rig.write(mode, pos_mode);
        break;
      case 5521:
        rig.write(cw, bit(reg::kEnable) | bit(reg::kExecute));
        break;
      case 5522:
        rig.write(cw, bit(reg::kEnable));
        break;
      default:
        break;
    }
    if (i < 4500 && i % 10 == 0) rig.write(heartbeat, static_cast<std::uint16_t>(i));
    rig.poll();
    rig.cycle();
    const Snapshot s = rig.ctl->snapshot();
    seen_states = static_cast<std::uint16_t>(seen_states | (1u << s.drive_state));
    max_twin_healthy =
        std::max<std::uint16_t>(max_twin_healthy, (s.status_word >> reg::kTwinHealthy) & 1u);
    lagged = lagged || ((s.status_word >> reg::kTwinLagging) & 1u);
    if (first_cycle == 0 && armed.count() != before) first_cycle = static_cast<std::uint64_t>(i);
  }
  const std::uint64_t allocations = armed.count();
  const std::size_t first_size = armed.first_size_bytes();
  const Snapshot s = rig.ctl->snapshot();
  EXPECT_EQ(allocations, 0u) << "first in cycle " << first_cycle << ", " << first_size << " bytes";
  // The run went where it was meant to: it is not a loop idling in one state.
  EXPECT_EQ(s.cycle, static_cast<std::uint64_t>(kCycles));
  EXPECT_EQ(seen_states, (1u << 1) | (1u << 2) | (1u << 3)) << "ready, enabled and fault";
  EXPECT_EQ(max_twin_healthy, 1u) << "the twin ran";
  EXPECT_FALSE(lagged);
  EXPECT_EQ(s.twin.cycle + 1, s.cycle) << "results of the previous cycle, drained after it";
  EXPECT_EQ(s.drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
  EXPECT_EQ(s.active_mode, static_cast<std::uint16_t>(reg::Mode::position));
  EXPECT_NEAR(s.nut_pos_m, 0.022, 0.5e-3);
}

// The same with a model whose terms the twin evaluates every cycle (names looked up without
// building strings).
TEST(NoAllocation, ModelTermsInTheTwinAllocateNothing) {
  Rig rig(true, true);
  const std::uint16_t cw = reg::find("control_word")->address;
  const std::uint16_t mode = reg::find("mode_command")->address;
  const std::uint16_t pos = reg::find("position_setpoint_um")->address;
  for (int i = 0; i < 20; ++i) rig.cycle();  // set-up (first snapshots) before arming
  test_support::AllocationCount armed;
  for (int i = 1; i <= 3000; ++i) {
    switch (i) {
      case 10:
        rig.write(cw, bit(reg::kEnable));
        break;
      case 20:
        rig.write32(pos, 25000);
        break;
      case 21:
        rig.write(mode, static_cast<std::uint16_t>(reg::Mode::position));
        break;
      case 22:
        rig.write(cw, bit(reg::kEnable) | bit(reg::kExecute));
        break;
      case 23:
        rig.write(cw, bit(reg::kEnable));
        break;
      default:
        break;
    }
    rig.cycle();
    if (i % 10 == 0) rig.poll();
  }
  EXPECT_EQ(armed.count(), 0u) << "first allocation of " << armed.first_size_bytes() << " bytes";
}
