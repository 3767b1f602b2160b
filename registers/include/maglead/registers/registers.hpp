#pragma once
// The Modbus register map of a maglead controller: one table, from which the server mapping,
// docs/registers.md, the CSV/JSON exports and the operator tools' names all come.
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace maglead::registers {

enum class Table : std::uint8_t { coil, discrete_input, input_register, holding_register };
enum class Type : std::uint8_t { bit, u16, i16, u32, i32, f32 };
enum class Access : std::uint8_t { read_only, read_write };

/// One entry. Physical value (SI) = raw × scale; `min`/`max` are in SI units and bound what
/// a client may write (for read-only entries they describe the expected span).
struct Register {
  std::string_view name;
  Table table;
  std::uint16_t address;
  Type type;
  double scale;
  std::string_view unit;
  Access access;
  double min;
  double max;
  std::string_view description;
};

/// Status word bits; also the discrete-input addresses.
enum StatusBit : std::uint16_t {
  kReady = 0,
  kEnabled,
  kFault,
  kMoving,
  kInPosition,
  kForceReached,
  kStepOut,
  kDriftWarning,
  kWatchdogExpired,
  kTwinHealthy,
  kStepOutWarning,
  kStopped,
  kOwned,
  kStrokeLimit,
  kTwinLagging,
  kForceLimited,
};
/// Control word bits; also the coil addresses. enable/stop are levels, the rest act on edges.
enum ControlBit : std::uint16_t { kEnable = 0, kStop, kFaultReset, kResync, kExecute };
inline constexpr std::uint16_t kControlWordMask = 0x1F;
/// command_status bits: acknowledge (edge seen, cleared when the bit falls) and done.
enum CommandBit : std::uint16_t {
  kExecuteAck = 0,
  kExecuteDone,
  kResetAck,
  kResetDone,
  kResyncAck,
  kResyncDone,
  kRejected,
};
enum class DriveState : std::uint16_t { disabled = 0, ready = 1, enabled = 2, fault = 3 };
enum class Mode : std::uint16_t { idle = 0, position = 1, force = 2, reference_move = 3 };
enum class Alarm : std::uint16_t {
  none = 0,
  step_out = 1,
  phase_jump = 2,
  watchdog = 3,
  stroke_limit = 4,
  sensor_fault = 5,
  drive_fault = 6,
  owner_lost = 7,
  following_error = 8,
};
/// The fault reaction the drive is carrying out (register fault_reaction).
enum class Reaction : std::uint16_t {
  none = 0,
  releasing = 1,
  holding = 2,
  released = 3,
  drive_own = 4
};
/// Why the last write was refused with exception 03 or 04 (register write_refusal_reason):
/// refusals that retrying cannot fix.
enum class Refusal : std::uint16_t {
  none = 0,
  not_owner = 1,
  broadcast_state_change = 2,
  out_of_range = 3,
  force_beyond_safe_limit = 4,
  position_outside_stroke = 5,
  bad_control_word = 6,
  word_order = 7,
  copies_disagree = 8,
};
enum class Reject : std::uint16_t {
  none = 0,
  not_enabled = 1,
  in_fault = 2,
  force_beyond_safe_limit = 3,
  target_outside_stroke = 4,
  stopped = 5,
  still_faulty = 6,
  not_stepped_out = 7,
  fault_returned = 8,
};

struct Code {
  std::uint16_t value;
  std::string_view name;
  std::string_view description;
};
std::span<const Code> alarm_codes();
std::span<const Code> reject_codes();
std::span<const Code> drive_states();
std::span<const Code> modes();
std::span<const Code> reactions();
std::span<const Code> refusals();
/// command_status's bits (IR 15): value is the bit number (CommandBit).
std::span<const Code> command_bits();
/// The codes of a register that holds one (drive_state, alarm_code, force_loop_state …); empty
/// for a register that holds a quantity.
std::span<const Code> codes_of(std::string_view register_name);
/// Every code list once, named by the registers that hold it ("active_mode / mode_command"), in
/// the table's order: what the docs list.
std::vector<std::pair<std::string, std::span<const Code>>> code_lists();

/// Identity and word-order probe values.
inline constexpr std::uint16_t kDeviceType = 0x4D4C;  // "ML"
inline constexpr std::uint16_t kMapVersion = 2;  // raised whenever a register is added or changed
inline constexpr std::uint32_t kWordOrderProbeU32 = 0x12345678u;
inline constexpr float kWordOrderProbeF32 = 1234.5678f;

std::span<const Register> table();

/// Address ranges of the map. Inside them, addresses no register uses are reserved: they read
/// as 0 and refuse writes, so that a block read across them works.
struct AddressRange {
  Table table;
  std::uint16_t first, count;
  std::string_view what;
};
std::span<const AddressRange> mapped_ranges();
/// The requests a PLC or SCADA system should poll (each within 125 registers).
std::span<const AddressRange> poll_blocks();
/// True when (table, address) lies inside a mapped range (used or reserved).
bool in_mapped_range(Table table, std::uint16_t address);
/// nullptr when absent.
const Register* find(std::string_view name);
/// The entry covering (table, address) and which of its words it is; nullptr when unmapped.
const Register* at(Table table, std::uint16_t address, int* word_index = nullptr);

int word_count(Type type);
std::string_view to_string(Table table);
std::string_view to_string(Type type);
std::string_view to_string(Access access);

/// SI value to raw words, high word first (big-endian word order, as bytes within a word).
/// Scaled integers are rounded and saturate at the type's limits; NaN encodes as 0.
void encode(const Register& reg, double value_si, std::uint16_t* words);
double decode(const Register& reg, const std::uint16_t* words);
/// True when a write value lies in [min, max]: a scaled integer compared in its integer units
/// after encode's rounding (so a value within half a unit of a limit is the limit), a float32
/// with a relative 1e-6 for the limits' own float32 rounding.
bool in_range(const Register& reg, double value_si);

std::string to_markdown();
std::string to_csv();
std::string to_json();

}  // namespace maglead::registers
