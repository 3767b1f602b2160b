#include "maglead/modbus/modbus_rtu.hpp"

#include <modbus/modbus.h>
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace maglead::modbus {
namespace {

double mono_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

RtuServer::RtuServer(ModbusCore& core, RtuOptions options)
    : core_(core), options_(std::move(options)) {
  const char p = options_.parity;
  if (p != 'N' && p != 'E' && p != 'O') throw std::invalid_argument("parity must be N, E or O");
  if (options_.unit_id < 1 || options_.unit_id > 247)
    throw std::invalid_argument("RTU unit id must be 1..247");
  if (options_.stop_bits != 1 && options_.stop_bits != 2)
    throw std::invalid_argument("stop bits must be 1 or 2");
  if (options_.data_bits < 7 || options_.data_bits > 8)
    throw std::invalid_argument("data bits must be 7 or 8");
  modbus_t* ctx = modbus_new_rtu(options_.device.c_str(), options_.baud, p, options_.data_bits,
                                 options_.stop_bits);
  if (!ctx) throw std::runtime_error("RTU " + options_.device + ": " + modbus_strerror(errno));
  modbus_set_slave(ctx, options_.unit_id);
  if (modbus_connect(ctx) != 0) {
    const std::string msg = "RTU " + options_.device + ": " + modbus_strerror(errno);
    modbus_free(ctx);
    throw std::runtime_error(msg);
  }
  if (options_.rs485 && modbus_rtu_set_serial_mode(ctx, MODBUS_RTU_RS485) != 0) {
    const std::string msg = "RTU " + options_.device + ": RS-485 mode: " + modbus_strerror(errno);
    modbus_close(ctx);
    modbus_free(ctx);
    throw std::runtime_error(msg);
  }
  ctx_ = ctx;
}

RtuServer::~RtuServer() {
  stop();
  auto* ctx = static_cast<modbus_t*>(ctx_);
  modbus_close(ctx);
  modbus_free(ctx);
}

void RtuServer::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { run(); });
}

void RtuServer::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
}

RtuTiming rtu_timing(int baud, int bits_per_char) {
  // Modbus over serial line V1.02, 2.5.1.1: t1.5 and t3.5 are 1.5 and 3.5 character times;
  // above 19200 Bd they are fixed at 750 us and 1.75 ms.
  if (baud > 19200) return {750e-6, 1750e-6};
  const double char_s = static_cast<double>(bits_per_char) / baud;
  return {1.5 * char_s, 3.5 * char_s};
}

void RtuServer::run() {
  auto* ctx = static_cast<modbus_t*>(ctx_);
  const int fd = modbus_get_socket(ctx);
  // A frame ends with t3.5 of silence; a partial frame followed by that silence is discarded,
  // so the next request is framed from its first byte. (t1.5 between the characters of a frame
  // is not enforced: USB adapters and pseudo-terminals deliver a frame in bursts.)
  const int bits = 1 + options_.data_bits + (options_.parity == 'N' ? 0 : 1) + options_.stop_bits;
  const double silence_s = rtu_timing(options_.baud, bits).t3_5_s;
  const int silence_ms = static_cast<int>(std::ceil(silence_s * 1000.0));
  std::uint8_t buf[kMaxRtuAdu * 2];
  std::size_t n = 0;
  double last_byte_s = 0.0;
  std::uint8_t pdu_out[ModbusCore::kMaxPdu + 1];
  const auto discard = [&] {
    core_.count_comm_error();  // truncated, oversized or broken: drop everything received
    n = 0;
  };
  while (running_.load(std::memory_order_relaxed)) {
    pollfd pfd{fd, POLLIN, 0};
    const int pr = poll(&pfd, 1, n == 0 ? 100 : silence_ms);
    const double now = mono_s();
    if (pr > 0 && (pfd.revents & POLLIN)) {
      // Silence since the last byte ended whatever was there: a new frame starts here.
      if (n > 0 && now - last_byte_s >= silence_s) discard();
      const ssize_t r = read(fd, buf + n, sizeof buf - n);
      if (r > 0) {
        n += static_cast<std::size_t>(r);
        last_byte_s = now;
      } else if (r < 0 && errno != EAGAIN && errno != EINTR) {
        std::fprintf(stderr, "maglead serve: RTU %s: %s; RTU stopped\n", options_.device.c_str(),
                     std::strerror(errno));
        return;
      }
    } else if (pr > 0 && (pfd.revents & (POLLHUP | POLLERR))) {
      // The other end of a pty went away; wait for it to come back rather than spin.
      poll(nullptr, 0, 50);
    }
    const bool silent = mono_s() - last_byte_s >= silence_s;
    while (n > 0) {
      const RtuFrame f = frame_rtu(buf, n, silent);
      if (f.status == FrameStatus::need_more) break;
      if (f.status == FrameStatus::error) {
        // Framing is lost: a whole request later in the buffer is served (the silence before
        // it was not seen), else everything goes and the next silence resynchronises.
        const std::size_t k = rtu_resync_offset(buf, n, silent);
        if (k == n) {
          discard();
          break;
        }
        core_.count_comm_error();
        std::memmove(buf, buf + k, n - k);
        n -= k;
        continue;
      }
      const std::size_t frame = f.size;
      const std::uint8_t unit = f.unit_id;
      const std::uint8_t fc = f.pdu[0];
      const bool broadcast = unit == 0;
      const bool broadcast_write = fc == 5 || fc == 6 || fc == 15 || fc == 16;
      if (unit == options_.unit_id || (broadcast && broadcast_write)) {
        const std::size_t len = core_.handle(ClientInfo{ModbusCore::kRtuClient, 0, broadcast},
                                             f.pdu, f.pdu_size, pdu_out + 1);
        if (len > 0) {
          pdu_out[0] = unit;
          modbus_send_raw_request(ctx, pdu_out, static_cast<int>(len + 1));
        }
      }
      std::memmove(buf, buf + frame, n - frame);
      n -= frame;
    }
  }
}

}  // namespace maglead::modbus
