#pragma once
// SocketCAN (Linux CAN_RAW): a non-blocking socket on one interface, waits bounded by poll, the
// controller's error frames and bus-off reported as statuses. Opening checks the interface and
// throws with how to bring one up; after that nothing throws or allocates.
#include <string>

#include "maglead/canopen/can_bus.hpp"

namespace maglead::canopen {

class SocketCanBus final : public CanBus {
 public:
  /// Opens `interface` (e.g. "can0"); throws std::runtime_error naming it when it is missing or
  /// down, with the command that brings a CAN interface up.
  explicit SocketCanBus(const std::string& interface);
  ~SocketCanBus() override;
  SocketCanBus(const SocketCanBus&) = delete;
  SocketCanBus& operator=(const SocketCanBus&) = delete;

  CanStatus send(const CanFrame& frame) noexcept override;
  CanStatus receive(CanFrame& out, double deadline_s) noexcept override;
  double now_s() noexcept override;
  CanCounters counters() const noexcept override { return counters_; }

 private:
  CanStatus read_one(CanFrame& out) noexcept;
  int fd_ = -1;
  CanCounters counters_;
};

/// What a SocketCAN error frame (CAN_ERR_FLAG set in `can_id`) reports: bus_off for
/// CAN_ERR_BUSOFF, error_frame for anything else. Pure, so tested without an interface.
CanStatus classify_error_frame(std::uint32_t can_id) noexcept;

}  // namespace maglead::canopen
