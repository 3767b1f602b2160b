#pragma once
// Transport-independent Modbus request handling: validates every request against the register
// table, answers exceptions at once, keeps the client-writable image and control ownership,
// and posts commands to the loop. TCP and RTU framers call handle() with bare PDUs.
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "maglead/controller/controller.hpp"

namespace maglead::modbus {

// The controller's snapshot exchange (one cycle's image out, commands in): all that Modbus
// knows of the controller.
using controller::Command;
using controller::CommandImage;
using controller::Controller;
using controller::Snapshot;

struct ServerOptions {
  bool read_only = false;  // every write is refused with exception 01
  std::string model_name = "simulated actuator";
};

struct ClientInfo {
  std::uint16_t id = 0;    // TCP connection number (1…), or kRtuClient
  std::uint32_t ipv4 = 0;  // host order; 0 for RTU
  bool broadcast = false;  // RTU unit 0: setpoint writes act, nothing is answered
};

/// Modbus exception codes used here.
enum class Exception : std::uint8_t {
  illegal_function = 1,
  illegal_data_address = 2,
  illegal_data_value = 3,
  server_device_failure = 4,
  server_busy = 6,
  gateway_target_failed = 0x0B,
};

class ModbusCore {
 public:
  static constexpr std::uint16_t kRtuClient = 0xFFFF;
  static constexpr std::size_t kMaxPdu = 253;

  /// Throws std::logic_error when the register table and the bindings disagree.
  ModbusCore(Controller& controller, ServerOptions options);

  /// Handles one request PDU (function code first). Writes the response PDU to `out`
  /// (kMaxPdu bytes) and returns its length; 0 means send nothing. Thread-safe.
  std::size_t handle(const ClientInfo& client, const std::uint8_t* pdu, std::size_t len,
                     std::uint8_t* out);
  /// Builds an exception response for a transport-level refusal (wrong unit id …).
  static std::size_t exception(std::uint8_t function, Exception code, std::uint8_t* out);

  void client_closed(std::uint16_t client_id);
  void count_comm_error();  // a frame with a bad CRC or broken framing

  std::uint16_t owner() const;

  struct Binding;  // how a table entry gets its value (defined in the .cpp)

 private:
  static constexpr std::int16_t kUnmapped = -1, kReservedInput = -2, kReservedHolding = -3;
  struct Slot {
    std::int16_t reg = kUnmapped;  // index into registers::table(), or unmapped / reserved
    std::int8_t word = 0;
  };
  std::size_t dispatch(const ClientInfo& client, const std::uint8_t* pdu, std::size_t len,
                       std::uint8_t* out);
  // One handler per function code (group); each takes the whole PDU and returns the reply length.
  std::size_t handle_read_bits(const std::uint8_t* pdu, std::size_t len, std::uint8_t* out);
  std::size_t handle_read_registers(const std::uint8_t* pdu, std::size_t len, std::uint8_t* out);
  std::size_t handle_write_coil(const ClientInfo& client, const std::uint8_t* pdu, std::size_t len,
                                std::uint8_t* out);
  std::size_t handle_write_coils(const ClientInfo& client, const std::uint8_t* pdu, std::size_t len,
                                 std::uint8_t* out);
  std::size_t handle_write_register(const ClientInfo& client, const std::uint8_t* pdu,
                                    std::size_t len, std::uint8_t* out);
  std::size_t handle_write_registers(const ClientInfo& client, const std::uint8_t* pdu,
                                     std::size_t len, std::uint8_t* out);
  std::size_t handle_read_write_registers(const ClientInfo& client, const std::uint8_t* pdu,
                                          std::size_t len, std::uint8_t* out);
  std::size_t handle_diagnostics(const std::uint8_t* pdu, std::size_t len, std::uint8_t* out);
  std::size_t handle_device_identification(const std::uint8_t* pdu, std::size_t len,
                                           std::uint8_t* out);
  std::size_t write_registers_and_echo(const ClientInfo& client, std::uint16_t start,
                                       std::uint16_t count, const std::uint8_t* data,
                                       const std::uint8_t* pdu, std::uint8_t* out);
  std::size_t apply_and_echo(const ClientInfo& client, const CommandImage& next, bool heartbeat,
                             bool touches_control, const std::uint8_t* pdu, std::uint8_t* out);
  bool diagnostic_value(std::uint16_t sub, std::uint16_t data, std::uint16_t& value);
  std::size_t device_identification_reply(std::uint8_t code, std::size_t first, std::size_t last,
                                          std::uint8_t* out) const;
  std::size_t read_registers(bool input_only, std::uint16_t start, std::uint16_t count,
                             std::uint8_t* out, std::size_t& n, Exception& ex);
  bool write_image(const ClientInfo& client, CommandImage next, bool heartbeat,
                   bool touches_control, Exception& ex);
  bool decode_registers(std::uint16_t start, std::uint16_t count, const std::uint8_t* data,
                        CommandImage& image, bool& heartbeat, bool& touches_control, Exception& ex);
  double read_value(std::size_t reg_index, const Snapshot& snap) const;
  void check_limits_fit_the_map() const;
  // Registers that read the configuration (the loop rate, the limits block), not the loop.
  std::optional<double> configured_value(std::string_view name) const;
  bool refuse(registers::Refusal why, Exception& ex);        // exception 04 with its reason; false
  bool refuse_value(registers::Refusal why, Exception& ex);  // exception 03 with its reason
  void stage_position_until_written();

  Controller& controller_;
  ServerOptions options_;
  mutable std::mutex mutex_;  // between network threads only; the loop never takes it
  std::vector<Slot> reg_slots_, coil_slots_, di_slots_;
  std::vector<const Binding*> bindings_;           // per table entry
  std::vector<std::optional<double>> configured_;  // per table entry: configured_value's
  CommandImage image_;
  bool target_written_ = false;  // a client wrote a position target (stage_position_until_written)
  bool request_writes_target_ = false;  // the request being handled writes one
  std::uint16_t owner_ = 0;
  std::uint32_t owner_ipv4_ = 0;
  std::uint16_t refusal_ = 0;  // registers::Refusal of the last write refused (03 or 04)
  // Diagnostics counters (function 8).
  std::uint16_t bus_messages_ = 0, comm_errors_ = 0, exceptions_ = 0, server_messages_ = 0,
                no_response_ = 0, busy_ = 0;
};

}  // namespace maglead::modbus
