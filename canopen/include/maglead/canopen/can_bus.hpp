#pragma once
// The CAN transport behind a narrow interface: one frame out, one frame in before a deadline.
// The master and the simulated drive know only this; SocketCAN and the in-process virtual bus
// implement it. Nothing here throws or allocates once constructed: the loop's cycle calls it.
#include <array>
#include <cstdint>

namespace maglead::canopen {

/// A classic CAN frame (11-bit identifier, up to 8 data bytes).
struct CanFrame {
  std::uint32_t id = 0;  // 11-bit COB-ID
  std::uint8_t len = 0;  // data length code, 0..8
  std::array<std::uint8_t, 8> data{};
};

enum class CanStatus : std::uint8_t {
  ok,
  timeout,      // no frame before the deadline
  tx_busy,      // the transmit queue is full: the frame was not sent
  error_frame,  // the controller reported a bus error (the frame holds its detail)
  bus_off,      // the controller left the bus: nothing is sent until it is restarted
  io_error,     // the socket failed otherwise
};

const char* can_status_text(CanStatus status) noexcept;

/// What a bus has seen since it was opened; read by the master for its counters.
struct CanCounters {
  std::uint64_t sent = 0, received = 0, tx_busy = 0, error_frames = 0, bus_off = 0;
};

class CanBus {
 public:
  virtual ~CanBus() = default;
  virtual CanStatus send(const CanFrame& frame) noexcept = 0;
  /// The next frame for this node. Waits at most until `deadline_s` on now_s()'s clock; a
  /// deadline at or before now only takes what has already arrived.
  virtual CanStatus receive(CanFrame& out, double deadline_s) noexcept = 0;
  /// The bus's clock [s]: CLOCK_MONOTONIC on SocketCAN, simulated time on the virtual bus.
  virtual double now_s() noexcept = 0;
  virtual CanCounters counters() const noexcept = 0;
};

/// Bits one frame takes on the wire at worst, with the most stuff bits and the 3-bit interframe
/// space (CAN 2.0A; Davis et al., "CAN schedulability analysis refuted, revisited", 2007).
constexpr int frame_bits_worst(int data_bytes) {
  return 8 * data_bytes + 47 + (34 + 8 * data_bytes - 1) / 4;
}

}  // namespace maglead::canopen
