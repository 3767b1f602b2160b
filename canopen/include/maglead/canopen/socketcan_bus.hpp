#pragma once
// SocketCAN (Linux CAN_RAW): a non-blocking socket on one interface, waits bounded by poll, the
// controller's error frames and bus-off reported as statuses. Opening checks the interface and
// throws with how to bring one up; after that nothing throws or allocates.
#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "maglead/canopen/can_bus.hpp"

namespace maglead::canopen {

/// One receive filter of CAN_RAW: a frame passes when (its id & mask) == (id & mask).
struct CanIdFilter {
  std::uint32_t id = 0, mask = 0;
};
/// What the master for drive `node_id` receives: its EMCY, TPDO1, TPDO2, SDO responses and
/// heartbeat, standard frames only, no remote frames. Pure, so tested without an interface.
std::array<CanIdFilter, 5> drive_receive_filter(std::uint8_t node_id) noexcept;

class SocketCanBus final : public CanBus {
 public:
  /// Opens `interface` (e.g. "can0"); throws std::runtime_error naming it when it is missing or
  /// down, with the command that brings a CAN interface up.
  /// `bitrate_bit_s`: the drive's, for the hint to bring the interface up at it.
  explicit SocketCanBus(const std::string& interface, std::uint32_t bitrate_bit_s = 1'000'000);
  ~SocketCanBus() override;
  SocketCanBus(const SocketCanBus&) = delete;
  SocketCanBus& operator=(const SocketCanBus&) = delete;

  /// Set-up: the kernel passes only frames that match one of `filters` (error frames keep
  /// coming), so traffic of other nodes on a shared bus never reaches the cycle's receive.
  /// Throws std::runtime_error when the socket refuses them.
  void set_receive_filter(std::span<const CanIdFilter> filters);

  CanStatus send(const CanFrame& frame) noexcept override;
  CanStatus receive(CanFrame& out, double deadline_s) noexcept override;
  double now_s() noexcept override;
  CanCounters counters() const noexcept override { return counters_; }

 private:
  CanStatus read_one(CanFrame& out) noexcept;
  std::string interface_;
  int fd_ = -1;
  CanCounters counters_;
};

/// What a SocketCAN error frame (CAN_ERR_FLAG set in `can_id`) reports: bus_off for
/// CAN_ERR_BUSOFF, error_frame for anything else. Pure, so tested without an interface.
CanStatus classify_error_frame(std::uint32_t can_id) noexcept;

}  // namespace maglead::canopen
