#include "maglead/canopen/virtual_bus.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace maglead::canopen {

VirtualCanPort::VirtualCanPort(VirtualCanBus& bus, std::uint8_t node_id, std::size_t capacity)
    : bus_(bus), node_id_(node_id), ring_(capacity) {}

CanStatus VirtualCanPort::send(const CanFrame& frame) noexcept {
  ++counters_.sent;
  bus_.transmit(*this, frame);
  return CanStatus::ok;
}

double VirtualCanPort::now_s() noexcept { return bus_.now_s(); }

void VirtualCanPort::enqueue(const CanFrame& frame, double deliver_s) noexcept {
  if (size_ == ring_.size()) {
    ++overflows_;
    return;
  }
  ring_[(head_ + size_) % ring_.size()] = Queued{frame, deliver_s};
  ++size_;
}

bool VirtualCanPort::take_due(CanFrame& out, double now_s) noexcept {
  if (size_ == 0 || ring_[head_].deliver_s > now_s) return false;
  out = ring_[head_].frame;
  head_ = (head_ + 1) % ring_.size();
  --size_;
  ++counters_.received;
  return true;
}

CanStatus VirtualCanPort::receive(CanFrame& out, double deadline_s) noexcept {
  for (;;) {
    if (take_due(out, bus_.now_s())) return CanStatus::ok;
    // Devices receive only what has arrived; the tick loop is the master's to run.
    if (bus_.ticking_ || bus_.now_s() >= deadline_s) return CanStatus::timeout;
    bus_.tick();
  }
}

VirtualCanBus::VirtualCanBus(VirtualBusOptions options) : options_(options), rng_(options.seed) {
  if (!(options_.tick_s > 0.0) || !(options_.latency_s >= 0.0))
    throw std::invalid_argument("virtual CAN bus: the tick must be positive, the latency >= 0 [s]");
  if (!(options_.drop_fraction >= 0.0 && options_.drop_fraction < 1.0))
    throw std::invalid_argument("virtual CAN bus: the drop fraction must lie in [0, 1)");
  silent_from_s_.fill(std::numeric_limits<double>::infinity());
}

VirtualCanPort& VirtualCanBus::attach(std::uint8_t node_id) {
  if (node_id >= silent_from_s_.size())
    throw std::invalid_argument("virtual CAN bus: a node id lies in 0..127");
  ports_.push_back(std::make_unique<VirtualCanPort>(*this, node_id, options_.queue_frames));
  return *ports_.back();
}

void VirtualCanBus::silence(std::uint8_t node_id, double from_s) noexcept {
  if (node_id < silent_from_s_.size()) silent_from_s_[node_id] = from_s;
}

void VirtualCanBus::transmit(const VirtualCanPort& from, const CanFrame& frame) noexcept {
  if (now_s_ >= silent_from_s_[from.node_id()]) {
    ++silenced_;
    return;
  }
  if (options_.drop_fraction > 0.0 && uniform_(rng_) < options_.drop_fraction) {
    ++dropped_;
    return;
  }
  ++carried_;
  for (const auto& port : ports_)
    if (port.get() != &from) port->enqueue(frame, now_s_ + options_.latency_s);
}

void VirtualCanBus::tick() noexcept {
  now_s_ += options_.tick_s;
  ticking_ = true;
  for (VirtualDevice* device : devices_) device->poll(now_s_);
  ticking_ = false;
}

void VirtualCanBus::advance_to(double t_s) noexcept {
  // Half a tick of slack so that t_s = k·tick reached by repeated addition is not overshot.
  while (now_s_ + 0.5 * options_.tick_s < t_s) tick();
}

}  // namespace maglead::canopen
