#pragma once
// The master and the simulated drive on one virtual bus, in simulated time: a test moves time
// with cycles() (the loop's period), never with real sleeps.
#include <cstdint>

#include "maglead/canopen/master.hpp"
#include "maglead/canopen/simulated_drive.hpp"
#include "maglead/canopen/virtual_bus.hpp"
#include "maglead/plant/simulated_actuator.hpp"

namespace maglead::canopen::testing {

struct Rig {
  explicit Rig(VirtualBusOptions bus_options = {}, DriveConfig drive_config = {},
               SimulatedDriveOptions drive_options = {})
      : bus(bus_options),
        actuator(paper_like_plant(), 7, 0.02),
        drive(bus, actuator, drive_options),
        port(bus.attach(0)),
        config(drive_config),
        master(port, config) {}

  /// `n` loop cycles: time moves one period, then the master runs its cycle.
  void cycles(int n) {
    for (int i = 0; i < n; ++i) {
      bus.advance_to(bus.now_s() + config.loop_period_s);
      master.cycle(bus.now_s());
    }
  }
  /// Cycles until the master sees `state` (at most `max_cycles`); true if it did.
  bool cycles_until(DriveState state, int max_cycles) {
    for (int i = 0; i < max_cycles; ++i) {
      cycles(1);
      if (master.feedback().state == state) return true;
    }
    return false;
  }
  /// Started and in operation enabled, the target held at the actual position.
  void enable() {
    master.start();
    master.request(DriveRequest::enabled);
    cycles_until(DriveState::operation_enabled, 20);
    master.set_target_counts(master.feedback().position_counts);
  }

  VirtualCanBus bus;
  SimulatedActuator actuator;
  SimulatedCia402Drive drive;
  VirtualCanPort& port;
  DriveConfig config;
  Cia402Master master;
};

}  // namespace maglead::canopen::testing
