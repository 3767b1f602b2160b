// The threads of `maglead serve` together: the loop on LoopRunner's thread (real clock) with
// the twin on its own thread (runtime::TwinRunner), the Modbus TCP server's network thread, and
// client threads (libmodbus) that poll while one of them owns the drive and commands a move.
// Asserts what the clients see, nothing about time; its point is to run under ThreadSanitizer
// (label `threads`).
#include <gtest/gtest.h>
#include <modbus.h>

#include <atomic>
#include <thread>
#include <vector>

#include "maglead/controller/loop_runner.hpp"
#include "maglead/modbus/modbus_core.hpp"
#include "maglead/modbus/modbus_tcp.hpp"
#include "maglead/plant/simulated_actuator.hpp"
#include "maglead/runtime/twin_runner.hpp"
#include "maglead/settings/settings.hpp"
#include "maglead/twin/monitor.hpp"

using namespace maglead;
using namespace maglead::controller;
using namespace maglead::modbus;
namespace reg = maglead::registers;

namespace {

modbus_t* connect(int port) {
  modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
  if (ctx == nullptr) return nullptr;
  modbus_set_slave(ctx, 1);
  modbus_set_response_timeout(ctx, 5, 0);
  if (modbus_connect(ctx) != 0) {
    modbus_free(ctx);
    return nullptr;
  }
  return ctx;
}

}  // namespace

TEST(ServeThreads, LoopTwinNetworkAndClientsTogether) {
  SimulatedActuator plant(paper_like_plant(), 4, 0.02);
  ControllerConfig cfg;
  Controller ctl(cfg, plant);
  twin::TwinMonitorConfig tc = twin::load_monitor_config(MAGLEAD_CONFIG_DIR);
  tc.actuator = cfg.actuator;
  tc.calibration = cfg.calibration;
  tc.integrator.max_step_s = 1.0 / cfg.actuator.sample_rate_hz;
  runtime::TwinRunner twin(tc);
  ctl.attach_twin(&twin);
  twin.start();
  ModbusCore core(ctl, {false, "test"});
  TcpOptions opt;
  opt.port = 0;
  TcpServer server(core, opt);
  LoopRunner loop(ctl);
  loop.start();
  server.start();

  const std::uint16_t cw = reg::find("control_word")->address;
  const std::uint16_t mode = reg::find("mode_command")->address;
  const std::uint16_t pos = reg::find("position_setpoint_um")->address;
  const std::uint16_t status = reg::find("status_word")->address;
  constexpr int kPollers = 3, kReads = 200;
  std::atomic<int> failed_reads{0}, connected{0};
  std::vector<std::thread> pollers;
  pollers.reserve(kPollers);
  for (int c = 0; c < kPollers; ++c) {
    pollers.emplace_back([&] {
      modbus_t* ctx = connect(server.port());
      if (ctx == nullptr) return;
      connected.fetch_add(1);
      std::uint16_t regs[56];
      for (int i = 0; i < kReads; ++i)
        if (modbus_read_input_registers(ctx, 0, 56, regs) != 56) failed_reads.fetch_add(1);
      modbus_close(ctx);
      modbus_free(ctx);
    });
  }
  // The owner: enable, then a move to 22 mm, on its own connection, while the others poll.
  modbus_t* owner = connect(server.port());
  ASSERT_NE(owner, nullptr);
  const std::uint16_t enable = 1u << reg::kEnable, execute = 1u << reg::kExecute;
  const std::uint16_t target[2] = {0, 22'000};  // i32, high word first: 22 000 µm
  EXPECT_EQ(modbus_write_register(owner, cw, enable), 1);
  EXPECT_EQ(modbus_write_registers(owner, pos, 2, target), 2);
  EXPECT_EQ(modbus_write_register(owner, mode, static_cast<std::uint16_t>(reg::Mode::position)), 1);
  EXPECT_EQ(modbus_write_register(owner, cw, enable | execute), 1);
  EXPECT_EQ(modbus_write_register(owner, cw, enable), 1);
  for (auto& t : pollers) t.join();
  EXPECT_EQ(connected.load(), kPollers);
  EXPECT_EQ(failed_reads.load(), 0);
  // The loop applies the owner's commands at its next cycle: read until the network shows
  // them (bounded by a count of reads, not by time): enabled (status) and moving or arrived.
  std::uint16_t words[8] = {};
  bool seen = false;
  for (int i = 0; i < 20'000 && !seen; ++i) {
    ASSERT_EQ(modbus_read_input_registers(owner, status, 8, words), 8);
    seen = (words[0] & (1u << reg::kEnabled)) &&
           ctl.snapshot().active_mode == static_cast<std::uint16_t>(reg::Mode::position);
  }
  EXPECT_TRUE(seen) << words[0];
  const Snapshot s = ctl.snapshot();
  EXPECT_EQ(s.drive_state, static_cast<std::uint16_t>(reg::DriveState::enabled));
  EXPECT_EQ(s.active_mode, static_cast<std::uint16_t>(reg::Mode::position));
  EXPECT_DOUBLE_EQ(s.active_target_pos_m, 0.022);
  modbus_close(owner);
  modbus_free(owner);
  server.stop();
  loop.stop();
  twin.stop();
  EXPECT_TRUE(ctl.snapshot().twin.cycle > 0) << "the twin thread published results";
}
