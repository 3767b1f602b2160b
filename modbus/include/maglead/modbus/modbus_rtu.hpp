#pragma once
// Modbus RTU slave on a serial line. libmodbus opens and configures the line (baud, parity,
// stop bits, RS-485) and frames our replies with their CRC; requests are framed here, from
// each function's length, because libmodbus 3.1.6 cannot frame function 8 or 43 requests.
#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

#include "maglead/modbus/framing.hpp"
#include "maglead/modbus/modbus_core.hpp"

namespace maglead::modbus {

struct RtuOptions {
  std::string device;  // e.g. /dev/ttyUSB0, or a pty from socat
  int baud = 19200;
  char parity = 'E';  // N, E or O
  int data_bits = 8;
  int stop_bits = 1;
  std::uint8_t unit_id = 1;  // 1..247; unit 0 is broadcast
  bool rs485 = false;
};

class RtuServer {
 public:
  /// Opens the line; throws std::runtime_error naming the device on failure.
  RtuServer(ModbusCore& core, RtuOptions options);
  ~RtuServer();
  RtuServer(const RtuServer&) = delete;
  RtuServer& operator=(const RtuServer&) = delete;
  void start();
  void stop();

 private:
  void run();
  ModbusCore& core_;
  RtuOptions options_;
  void* ctx_ = nullptr;  // modbus_t*, owned by this server's thread once started
  std::thread thread_;
  std::atomic<bool> running_{false};
};

/// Inter-character (t1.5) and inter-frame (t3.5) times of the serial line [s].
struct RtuTiming {
  double t1_5_s, t3_5_s;
};
/// From the baud rate and the bits per character (start + data + parity + stop); fixed at
/// 750 us / 1.75 ms above 19200 Bd, as the serial-line specification says.
RtuTiming rtu_timing(int baud, int bits_per_char);

}  // namespace maglead::modbus
