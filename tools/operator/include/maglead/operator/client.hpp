#pragma once
// A Modbus client for maglead controllers (TCP or RTU), speaking in register-table names and
// SI values: what the operator commands (poll, watch, set, enable, record …) share. Scaled
// integers exist only inside this library, through registers::encode / decode.
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/registers/registers.hpp"

namespace maglead::op {

struct Endpoint {
  std::string host = "127.0.0.1";
  int port = 1502;
  std::string serial;  // non-empty: Modbus RTU on this device instead of TCP
  int baud = 19200;
  char parity = 'E';
  int data_bits = 8;
  int stop_bits = 1;
  int unit = 1;
  double timeout_s = 1.0;        // per request
  std::string describe() const;  // "127.0.0.1:1502 unit 1" / "/dev/ttyUSB0 19200 8E1 unit 3"
};

/// Everything that can go wrong, each with a one-line message meant for an operator.
class ClientError : public std::runtime_error {
 public:
  enum class Kind : std::uint8_t {
    refused_locally,  // a value failed the checks: nothing was sent
    connection,       // cannot connect, or the connection dropped
    no_reply,         // timeout: wrong unit id (RTU), wrong line settings, controller off
    exception,        // the controller answered with a Modbus exception
    rejected,         // the controller rejected an edge command (command_reject_reason)
    protocol,         // a malformed or mismatched reply, or not a maglead controller
    interrupted,      // Ctrl-C or SIGTERM before the command was done
  };
  ClientError(Kind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}
  Kind kind() const { return kind_; }
  /// Exit codes: 2 refused locally, 3 communication, 4 refused by the controller, 130
  /// interrupted before done (the shell's code for Ctrl-C).
  int exit_code() const;

 private:
  Kind kind_;
};

/// Named values of one read, SI units; raw words kept for --raw.
struct Values {
  std::vector<const registers::Register*> regs;
  std::vector<double> si;
  std::vector<std::uint32_t> raw;  // the register's words as one number (bit pattern for f32)
  std::optional<double> get(std::string_view name) const;
  double at(std::string_view name) const;  // throws ClientError(protocol) when absent
};

/// Contiguous runs of one table that one request can read (≤125 words, 32-bit values whole).
struct Block {
  registers::Table table;
  std::uint16_t start, count;
};
std::vector<Block> read_blocks(registers::Table table);

class Client {
 public:
  /// Connects; throws ClientError with the reason.
  explicit Client(const Endpoint& endpoint);
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  const Endpoint& endpoint() const { return ep_; }

  /// Reads the device type and map version and refuses anything that is not a maglead
  /// controller speaking this register map version.
  void check_identity();
  /// Reads words [start, start+count) of a table (FC4 for input registers, FC3 for holding).
  std::vector<std::uint16_t> read_words(registers::Table table, std::uint16_t start,
                                        std::uint16_t count);
  /// Reads every register of the given tables in as few requests as possible.
  Values read_tables(const std::vector<registers::Table>& tables);
  /// Reads the named registers whose addresses lie in one block (one request, one cycle).
  Values read_range(registers::Table table, std::uint16_t start, std::uint16_t count);
  /// Writes named registers, each checked with registers::in_range first (nothing is sent when
  /// one fails). Consecutive addresses go out in one FC16 request, in the given order.
  void write(const std::vector<std::pair<std::string, double>>& values);

  /// Flushes the line after a timeout so a late reply cannot be taken for the next one.
  void flush();

 private:
  [[noreturn]] void fail(const std::string& what) const;
  [[noreturn]] void refused_write(const std::string& what);
  struct WrittenValue {
    const registers::Register* r;
    double v;
  };
  [[noreturn]] void refused_value(const std::string& what,
                                  const std::vector<WrittenValue>& written);
  Endpoint ep_;
  void* ctx_ = nullptr;  // modbus_t*
};

// ---------------------------------------------------------------------------- values and units

/// "12.5", "20mm", "12.5N", "5 mm/s" → SI value for a quantity whose SI unit is `si_unit`
/// (N, m, m/s, m/s^2, s). Throws ClientError(refused_locally) naming the accepted units.
double parse_quantity(const std::string& text, std::string_view si_unit);

/// The name a value carries when shown in SI units: the register name with its raw unit suffix
/// replaced by the SI one (nut_pos_um -> nut_pos_m, force_est_mn -> force_est_n, watchdog_ms ->
/// watchdog_s); unscaled registers keep their name. The register name itself names the raw
/// integer (--raw).
std::string si_name(const registers::Register& reg);
/// The register whose name or SI name is `name`; nullptr when none.
const registers::Register* find_by_any_name(std::string_view name);
/// Decimal places of the register's resolution in SI units (scale 1e-6 -> 6; 0 for integers).
int si_decimals(const registers::Register& reg);
/// The SI value rounded to the register's resolution, as the nearest double to that decimal
/// (0.3, never 0.30000000000000004); float32 registers to 7 significant digits.
double si_rounded(const registers::Register& reg, double value_si);
/// The SI value as text at the register's resolution ("0.3", "20.0001", "1000").
std::string si_text(const registers::Register& reg, double value_si);

/// Name and meaning of a code (alarm, reject reason, drive state, mode); "unknown (N)" if none.
std::string code_name(std::span<const registers::Code> codes, double value);
std::string code_meaning(std::span<const registers::Code> codes, double value);
/// The names of the status bits that are set.
std::vector<std::string> status_bits(std::uint16_t status_word);
/// The bits set in command_status (IR 15), by name (registers::command_bits).
std::vector<std::string> command_bits(std::uint16_t command_status);
/// Whether the controller has a load cell: false on a backend without one (cia402), where its
/// float32 register reads NaN and the fixed-point one 0 N, a reading no load cell made. `v` holds
/// load_cell_force_n_f32.
bool has_load_cell(const Values& v);

/// The limits a controller reports in its limits block (IR 140-147): the ones it refuses
/// against, whatever configuration this machine holds.
struct ReportedLimits {
  double force_pull_n = 0, force_push_n = 0, stroke_min_m = 0, stroke_max_m = 0;
};
/// The limits the controller enforces: those it reports, else (a controller without the limits
/// block) from the same configuration it reads.
struct Limits {
  ActuatorParams actuator;
  ForceCalibration calibration;
  std::string calibration_source;
  std::string actuator_source =
      "built-in defaults";  // where stroke and safe_force_fraction come from
  std::optional<ReportedLimits> reported;
};
/// The controller's limits block; nothing when it has none (exception 02: a map before version 2).
std::optional<ReportedLimits> read_reported_limits(Client& client);
/// The allowed range of a force or position setpoint with where its limits are set, e.g.
/// "-38.4 .. 38.4 N (safe_force_fraction 0.8 in config/actuator.toml x calibration peaks
/// -48 / 48 N in config/calibration.toml)".
std::string force_limit_text(const Limits& limits);
/// The coupling at its safe limit short of the force: the load force the controller estimates
/// there (load_n) is what friction leaves of the limit (limit_n, when the controller reports it),
/// the most 'set force' can reach against this load.
std::string drive_limit_reached_text(double load_n, std::optional<double> limit_n);
std::string position_limit_text(const Limits& limits);
/// Checks an output-force setpoint as the server does (register range, then the calibrated
/// safe limit); returns the reason it would be refused, or nothing.
std::optional<std::string> check_force(const Limits& limits, double force_n);
std::optional<std::string> check_position(const Limits& limits, double position_m);
/// Check of any writable register, with the reason: its range (compared in the register's own
/// units, registers::in_range), and a non-zero value its resolution would round to 0 (refused
/// with the resolution and what to type: 0 writes a different meaning, not a smaller value).
std::optional<std::string> check_register(const registers::Register& reg, double value_si);

// ---------------------------------------------------------------------------- commands

struct CommandOptions {
  double ack_timeout_s = 2.0;    // the loop must see the edge within this
  double done_timeout_s = 30.0;  // and finish (in position / force reached) within this
  bool wait_done = true;
  double poll_period_s = 0.01;
  /// execute: take control first when nobody has it (clear an owner_lost fault, enable edge).
  bool claim = true;
  /// execute: stop waiting for done when this returns true (Ctrl-C); done then stays false.
  std::function<bool()> stop;
  /// execute: called once per poll while it waits for done (a progress line on a terminal).
  std::function<void(Client&)> waiting;
};
struct CommandResult {
  bool done = false;  // execute done (target reached) seen
  double elapsed_s = 0.0;
};

/// Stages a setpoint and applies it with an execute edge, following the handshake of
/// docs/registers.md: mode_command and the control word with execute in one write, wait for
/// ack or rejection (reason from command_reject_reason), drop execute, optionally wait for done.
/// `setpoints` are the staged registers written before the edge.
CommandResult execute(Client& client, registers::Mode mode,
                      const std::vector<std::pair<std::string, double>>& setpoints,
                      const CommandOptions& options);
/// Enable (rising edge of the enable level) and wait for drive_state enabled.
void enable(Client& client, const CommandOptions& options);
void disable(Client& client, const CommandOptions& options);
/// disable, then the state the drive is in, in words: "drive disabled …" only when it is not in
/// fault (a latched fault stays until a reset, and the text says what to type).
std::string disable_and_say(Client& client);
/// The command that clears a latched alarm: 'maglead reset --resync' after a step-out or a phase
/// jump (a plain reset is refused, still_faulty, while the phase sits a lead away), else
/// 'maglead reset'. Every piece of advice to reset takes its command from here.
/// `step_out_bit`: the status word's step_out bit, set after a slip whatever the alarm (a
/// stroke_limit fault the nut slipped into).
std::string reset_command(double alarm, bool step_out_bit = false);
/// "run 'COMMAND'" and `tail`, unless a reset cannot clear the fault yet: a drive or bus that is
/// gone (drive_fault_cause 2-4) is cleared only once it answers again, a drive that restarted (5)
/// only by starting serve again (only the start-up configures it): then what to do instead.
std::string reset_step(double alarm, double drive_fault_cause, const std::string& command,
                       const char* tail = "");
/// What clears a latched fault, said to a client that has not claimed control: "run 'COMMAND'
/// first" (reset_command) when nobody owns control; when another client owns it, the controller
/// refuses our reset (exception 04 not_owner), so the owner must clear it or let go first.
std::string reset_advice(Client& client, double alarm);
/// Who owns control when it is not this client ("the client at 10.0.0.5", "the RTU master"), or
/// nothing when nobody does or this client may write as the owner (the RTU master over RTU):
/// the controller refuses any other client's writes (exception 04 not_owner).
std::optional<std::string> other_owner(Client& client);
/// After a fault while this client may own control: clears enable when it does (the controller
/// takes the write), "control released (…): run 'maglead reset'"; else reset_advice.
std::string release_after_fault(Client& client, double alarm);
/// How often the tools feed the drive's communication watchdog (heartbeat) while they own
/// control, and the shortest watchdog_s they claim under: ten periods, room for a request's
/// round trip and a loaded machine's scheduling (a PC is no PLC: 0.1 s was seen to expire).
inline constexpr double kHeartbeatPeriod_s = 0.02;
inline constexpr double kShortestWatchdog_s = 0.2;
/// Refuses (refused_locally, nothing written) to claim control under a watchdog_s shorter than
/// kShortestWatchdog_s, with what to type: the drive would fault while this tool owns it.
void check_watchdog(Client& client, const std::string& what);
/// Fault reset edge (optionally a resync edge first), with the ack/done handshake.
void reset(Client& client, bool resync_first, const CommandOptions& options);
/// reset, then what it did in words; with no fault and no resync asked, nothing is sent and it
/// says so ("no fault to reset (drive_state …)").
std::string reset_and_say(Client& client, bool resync_first);
/// Keeps control for `seconds` (infinity: for ever) or until `stop` says so (polling, feeding a
/// watchdog); throws when the drive faults or is disabled meanwhile. A connection that closes
/// while it owns control makes the drive run its owner-loss fault reaction: release first
/// (`disable`) to end control without a fault.
void hold(Client& client, double seconds, const CommandOptions& options,
          const std::function<bool()>& stop = {});

}  // namespace maglead::op
