#include "maglead/canopen/socketcan_bus.hpp"

#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <stdexcept>
#include <vector>

#include "maglead/canopen/protocol.hpp"

namespace maglead::canopen {
namespace {

std::string bring_up_hint(const std::string& interface, std::uint32_t bitrate_bit_s) {
  return " (bring one up at the drive's bit rate with `ip link set " + interface +
         " up type can bitrate " + std::to_string(bitrate_bit_s) +
         "`; for a virtual test bus: `ip link add dev vcan0 type vcan && ip link set vcan0 up`)";
}

// An interface that exists but is down: a virtual one takes no bit rate.
std::string down_hint(const std::string& interface, std::uint32_t bitrate_bit_s) {
  return " (bring it up at the drive's bit rate with `ip link set " + interface +
         " up type can bitrate " + std::to_string(bitrate_bit_s) +
         "`; a virtual bus (vcan) has no bit rate: `ip link set " + interface + " up`)";
}

// A kernel without CAN_RAW support answers the socket call so; its module loads by name.
std::string socket_hint(int error) {
  return error == EAFNOSUPPORT || error == EPROTONOSUPPORT
             ? "; load the kernel's CAN support with `modprobe can_raw`"
             : "";
}

}  // namespace

CanStatus classify_error_frame(std::uint32_t can_id) noexcept {
  return (can_id & CAN_ERR_BUSOFF) != 0 ? CanStatus::bus_off : CanStatus::error_frame;
}

std::array<CanIdFilter, 5> drive_receive_filter(std::uint8_t node_id) noexcept {
  // The full 11-bit id, and the extended-frame and remote-request flags that must be clear.
  constexpr std::uint32_t exact = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;
  std::array<CanIdFilter, 5> filters{};
  const std::array<std::uint32_t, 5> function_codes{cob_emcy, cob_tpdo1, cob_tpdo2, cob_sdo_tx,
                                                    cob_heartbeat};
  for (std::size_t i = 0; i < filters.size(); ++i)
    filters[i] = {function_codes[i] + node_id, exact};
  return filters;
}

void SocketCanBus::set_receive_filter(std::span<const CanIdFilter> filters) {
  std::vector<can_filter> raw;
  raw.reserve(filters.size());
  for (const CanIdFilter& f : filters) raw.push_back({f.id, f.mask});
  const auto bytes = static_cast<socklen_t>(raw.size() * sizeof(can_filter));
  if (setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, raw.data(), bytes) != 0)
    throw std::runtime_error("CAN interface \"" + interface_ +
                             "\": the receive filter was refused (" + std::strerror(errno) + ")");
}

SocketCanBus::SocketCanBus(const std::string& interface, std::uint32_t bitrate_bit_s)
    : interface_(interface) {
  if (interface.empty() || interface.size() >= IFNAMSIZ)
    throw std::runtime_error("CAN interface name \"" + interface + "\" is not valid: 1 to " +
                             std::to_string(IFNAMSIZ - 1) +
                             " characters, as `ip link` lists it (e.g. can0)");
  const unsigned index = if_nametoindex(interface.c_str());
  if (index == 0)
    throw std::runtime_error("CAN interface \"" + interface + "\" does not exist" +
                             bring_up_hint(interface, bitrate_bit_s));
  fd_ = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd_ < 0)
    throw std::runtime_error("CAN interface \"" + interface + "\": no CAN_RAW socket (" +
                             std::strerror(errno) + ")" + socket_hint(errno));
  ifreq request{};
  std::strncpy(request.ifr_name, interface.c_str(), IFNAMSIZ - 1);
  const bool up = ioctl(fd_, SIOCGIFFLAGS, &request) == 0 && (request.ifr_flags & IFF_UP) != 0;
  // Every error class, so that bus-off and error-passive reach the master as statuses.
  const can_err_mask_t errors = CAN_ERR_MASK;
  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = static_cast<int>(index);
  if (!up || setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errors, sizeof errors) != 0 ||
      bind(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
    const std::string why = up ? std::strerror(errno) : "it is down";
    close(fd_);
    fd_ = -1;
    throw std::runtime_error("CAN interface \"" + interface + "\" cannot be used: " + why +
                             (up ? std::string() : down_hint(interface, bitrate_bit_s)));
  }
}

SocketCanBus::~SocketCanBus() {
  if (fd_ >= 0) close(fd_);
}

CanStatus SocketCanBus::send(const CanFrame& frame) noexcept {
  can_frame raw{};
  raw.can_id = frame.id & CAN_SFF_MASK;
  raw.can_dlc = frame.len;
  std::memcpy(raw.data, frame.data.data(), frame.len);
  if (write(fd_, &raw, sizeof raw) == static_cast<ssize_t>(sizeof raw)) {
    ++counters_.sent;
    return CanStatus::ok;
  }
  if (errno == EAGAIN || errno == ENOBUFS) {
    ++counters_.tx_busy;
    return CanStatus::tx_busy;
  }
  return errno == ENETDOWN ? CanStatus::bus_off : CanStatus::io_error;
}

CanStatus SocketCanBus::read_one(CanFrame& out) noexcept {
  can_frame raw{};
  const ssize_t n = read(fd_, &raw, sizeof raw);
  if (n != static_cast<ssize_t>(sizeof raw))
    return n < 0 && errno == EAGAIN ? CanStatus::timeout : CanStatus::io_error;
  out.id = raw.can_id & CAN_EFF_MASK;
  out.len = raw.can_dlc > 8 ? 8 : raw.can_dlc;
  std::memcpy(out.data.data(), raw.data, 8);
  if ((raw.can_id & CAN_ERR_FLAG) != 0) {
    const CanStatus status = classify_error_frame(raw.can_id);
    ++(status == CanStatus::bus_off ? counters_.bus_off : counters_.error_frames);
    return status;
  }
  ++counters_.received;
  return CanStatus::ok;
}

CanStatus SocketCanBus::receive(CanFrame& out, double deadline_s) noexcept {
  for (;;) {
    const CanStatus status = read_one(out);
    if (status != CanStatus::timeout) return status;
    const double wait_s = deadline_s - now_s();
    if (wait_s <= 0.0) return CanStatus::timeout;
    pollfd waiting{fd_, POLLIN, 0};
    const double whole_s = std::floor(wait_s);
    const timespec timeout{static_cast<time_t>(whole_s),
                           static_cast<long>((wait_s - whole_s) * 1e9)};
    const int ready = ppoll(&waiting, 1, &timeout, nullptr);
    if (ready == 0) return CanStatus::timeout;
    if (ready < 0 && errno != EINTR) return CanStatus::io_error;
  }
}

double SocketCanBus::now_s() noexcept {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

}  // namespace maglead::canopen
