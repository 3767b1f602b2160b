#pragma once
// An in-process CAN bus for tests and `--can sim`: deterministic simulated time, ports for the
// master and each simulated node, and fault injection (a seeded fraction of frames dropped, a
// node silenced from a time). Single-threaded: a port waiting in receive() advances the bus's
// clock in ticks and lets every attached device run, so a blocking SDO exchange and a drive
// answering it need no second thread and no real time passes.
#include <cstdint>
#include <memory>
#include <random>
#include <vector>

#include "maglead/canopen/can_bus.hpp"

namespace maglead::canopen {

/// Something on the virtual bus that acts by itself (a simulated drive): polled every tick.
class VirtualDevice {
 public:
  virtual ~VirtualDevice() = default;
  virtual void poll(double now_s) noexcept = 0;
};

struct VirtualBusOptions {
  // Fine enough that a 1 ms cycle sees SYNC, the drive's answer and the next SYNC apart.
  double tick_s = 50e-6;
  // A frame reaches the others this long after it is sent: about one 8-byte frame at 1 Mbit/s.
  double latency_s = 130e-6;
  double drop_fraction = 0.0;  // of every frame sent, dropped for all receivers
  std::uint64_t seed = 1;
  // Frames a port holds before further ones are lost (counted): many cycles of traffic.
  std::size_t queue_frames = 512;
};

class VirtualCanBus;

/// One node's view of the virtual bus.
class VirtualCanPort final : public CanBus {
 public:
  VirtualCanPort(VirtualCanBus& bus, std::uint8_t node_id, std::size_t capacity);
  CanStatus send(const CanFrame& frame) noexcept override;
  CanStatus receive(CanFrame& out, double deadline_s) noexcept override;
  double now_s() noexcept override;
  CanCounters counters() const noexcept override { return counters_; }
  std::uint8_t node_id() const noexcept { return node_id_; }
  std::uint64_t overflows() const noexcept { return overflows_; }

 private:
  friend class VirtualCanBus;
  struct Queued {
    CanFrame frame;
    double deliver_s;
  };
  void enqueue(const CanFrame& frame, double deliver_s) noexcept;
  bool take_due(CanFrame& out, double now_s) noexcept;

  VirtualCanBus& bus_;
  std::uint8_t node_id_;
  std::vector<Queued> ring_;  // allocated once; head_/size_ index it
  std::size_t head_ = 0, size_ = 0;
  std::uint64_t overflows_ = 0;
  CanCounters counters_;
};

class VirtualCanBus {
 public:
  explicit VirtualCanBus(VirtualBusOptions options = {});
  VirtualCanBus(const VirtualCanBus&) = delete;
  VirtualCanBus& operator=(const VirtualCanBus&) = delete;

  /// A port for node `node_id` (0 for the master); lives as long as the bus.
  VirtualCanPort& attach(std::uint8_t node_id);
  /// A device polled every tick (not owned; must outlive the bus's use).
  void add_device(VirtualDevice& device) { devices_.push_back(&device); }

  double now_s() const noexcept { return now_s_; }
  /// Moves simulated time to `t_s` tick by tick, polling every device at each tick.
  void advance_to(double t_s) noexcept;

  void set_drop_fraction(double fraction) noexcept { options_.drop_fraction = fraction; }
  /// Frames node `node_id` sends from `from_s` on reach nobody (a drive that falls silent).
  void silence(std::uint8_t node_id, double from_s) noexcept;
  std::uint64_t dropped() const noexcept { return dropped_; }
  std::uint64_t silenced() const noexcept { return silenced_; }
  std::uint64_t carried() const noexcept { return carried_; }

 private:
  friend class VirtualCanPort;
  void transmit(const VirtualCanPort& from, const CanFrame& frame) noexcept;
  void tick() noexcept;

  VirtualBusOptions options_;
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  double now_s_ = 0.0;
  std::vector<std::unique_ptr<VirtualCanPort>> ports_;
  std::vector<VirtualDevice*> devices_;
  std::array<double, 128> silent_from_s_{};  // per node id; +inf: speaks
  std::uint64_t dropped_ = 0, silenced_ = 0, carried_ = 0;
  bool ticking_ = false;  // a device's own receive() must not re-enter the tick loop
};

}  // namespace maglead::canopen
