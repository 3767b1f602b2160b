#pragma once
// A strict CANopen master for one CiA 402 drive in cyclic synchronous position mode.
// start() (set-up: waits, allocates, throws) resets the drive's communication, reads its
// identity, writes the configuration and reads every object back, and sets it operational.
// cycle() (the loop's path: never waits, never allocates, returns a status) takes what arrived
// (PDOs, EMCY, heartbeat), supervises the heartbeat and the PDOs, and sends the RPDO and SYNC.
#include <cstdint>
#include <string>
#include <vector>

#include "maglead/canopen/can_bus.hpp"
#include "maglead/canopen/cia402.hpp"
#include "maglead/canopen/protocol.hpp"
#include "maglead/canopen/sdo_client.hpp"

namespace maglead::canopen {

/// The `[drive]` settings, SI units. check_drive_config() refuses what cannot work.
struct DriveConfig {
  std::uint8_t node_id = 1;
  std::uint32_t bitrate_bit_s = 1'000'000;
  double loop_period_s = 1e-3;          // SYNC period and 0x60C2, the interpolation period
  double heartbeat_producer_s = 0.1;    // 0x1017, written to the drive
  double heartbeat_timeout_s = 0.3;     // the master latches a fault after this much silence
  double counts_per_motor_turn = 4096;  // the drive's position unit (quadrature counts)
  double gear_ratio = 6.6;              // motor turns per screw turn
  std::uint16_t second_encoder_index = 0x60E4;  // CiA 402 "additional position actual value"
  std::uint8_t second_encoder_sub = 1;
  double second_encoder_m_per_count = 0.0254 / 1176.0;  // the nut's encoder (paper: 21.6 µm)
  double sdo_timeout_s = 0.05;
  int sdo_attempts = 3;  // a timed-out SDO is tried again (a frame lost at start-up)
  // Consecutive cycles without the drive's TPDO1 before the master latches a fault: a lost
  // frame or two is survived (the last values are used), a drive that stopped answering is not.
  int max_missed_cycles = 5;
  double boot_timeout_s = 1.0;  // a drive answers NMT reset communication with a boot-up by then
};

/// Throws std::invalid_argument naming the setting that cannot work.
void check_drive_config(const DriveConfig& config);
/// The share of the bus the cycle's frames take at worst (SYNC, RPDO1, TPDO1, TPDO2, heartbeat).
double bus_load_fraction(const DriveConfig& config);
/// 0x60C2: `period_s` as value · 10^exponent s (value 1..255); false when it has no such form.
bool interpolation_period_code(double period_s, std::uint8_t& value, std::int8_t& exponent);

/// The PDO layout this master configures: RPDO1 controlword + target position; TPDO1
/// statusword + position actual + error code; TPDO2 the second encoder.
PdoMap rpdo1_map();
PdoMap tpdo1_map();
PdoMap tpdo2_map(const DriveConfig& config);

struct DriveIdentity {
  std::uint32_t device_type = 0, vendor_id = 0, product_code = 0, revision = 0, serial = 0;
  std::string device_name;  // 0x1008, empty where the drive has none
};
std::string describe_identity(const DriveIdentity& identity);

enum class MasterFault : std::uint8_t {
  none,
  heartbeat_lost,   // no heartbeat within the timeout: the drive is silent or off the bus
  pdo_timeout,      // max_missed_cycles cycles in a row without TPDO1
  drive_fault,      // the drive reports fault (statusword), its EMCY says why
  bus_off,          // the CAN controller left the bus
  drive_restarted,  // a boot-up message while running: the drive reset itself
};
const char* master_fault_text(MasterFault fault) noexcept;

struct DriveFeedback {
  std::uint16_t statusword = 0;
  DriveState state = DriveState::unknown;
  std::int32_t position_counts = 0;        // 0x6064
  std::int32_t second_encoder_counts = 0;  // the configured second encoder object
  std::uint16_t error_code = 0;            // 0x603F
  NmtState nmt = NmtState::unknown;
};

struct MasterCounters {
  std::uint64_t cycles = 0, missed_tpdo = 0, emergencies = 0, error_frames = 0, tx_busy = 0;
  std::uint64_t sdo_retries = 0;
};

class Cia402Master {
 public:
  Cia402Master(CanBus& bus, DriveConfig config);
  /// The start-up sequence; throws std::runtime_error saying which step or object failed.
  void start();
  /// One cycle at loop time `now_s`: receive(now_s), then transmit(). Returns fault().
  MasterFault cycle(double now_s) noexcept;
  /// The cycle's first half: takes what arrived (PDOs, EMCY, heartbeat) and supervises.
  MasterFault receive(double now_s) noexcept;
  /// The cycle's second half: the controlword and target in RPDO1, then SYNC. Split from
  /// receive() so that a loop can compute its command between them, without a cycle's delay.
  MasterFault transmit() noexcept;

  void request(DriveRequest request) noexcept;
  /// The position command [counts], taken in operation enabled. In every other state the
  /// master sets it to the actual position, so enabling never makes the drive jump.
  void set_target_counts(std::int32_t target_counts) noexcept { target_counts_ = target_counts; }

  const DriveIdentity& identity() const { return identity_; }
  const DriveFeedback& feedback() const noexcept { return feedback_; }
  const MasterCounters& counters() const noexcept { return counters_; }
  /// The master's latched fault (heartbeat, PDO, bus, restart), else the drive's own fault.
  MasterFault fault() const noexcept;
  /// The heartbeat supervision on its own (another fault may have latched first), and the loop
  /// time at which it found the drive silent.
  bool heartbeat_lost() const noexcept { return heartbeat_lost_; }
  double heartbeat_lost_at_s() const noexcept { return heartbeat_lost_at_s_; }
  /// The last EMCY with a code other than 0 (error reset).
  const Emergency& last_emergency() const noexcept { return last_emcy_; }
  /// What fault() means: for a drive fault the text of its error code (0x603F, else the EMCY).
  const char* alarm_text() const noexcept;
  std::uint16_t last_controlword() const noexcept { return controlword_; }

  /// Writes an object and reads it back; throws naming the object on an abort or a mismatch.
  void write_checked(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::size_t bytes);
  /// Reads an object (retried on timeout); throws naming it on failure.
  std::vector<std::uint8_t> read(std::uint16_t index, std::uint8_t sub);

 private:
  SdoResult upload(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t>& data);
  std::string timeout_advice(const SdoResult& r) const;
  void handle_frame(const CanFrame& frame, double now_s) noexcept;
  void take_pdo(const CanFrame& frame) noexcept;
  void supervise(double now_s) noexcept;
  void configure_pdo(std::uint16_t comm_index, std::uint32_t cob_id, const PdoMap& map);
  void read_identity();
  void await_boot_up();
  void latch(MasterFault fault) noexcept;

  CanBus& bus_;
  DriveConfig cfg_;
  SdoClient sdo_;
  PdoMap rpdo1_, tpdo1_, tpdo2_;
  Cia402Sequencer sequencer_;
  DriveIdentity identity_;
  DriveFeedback feedback_;
  MasterCounters counters_;
  Emergency last_emcy_;
  MasterFault fault_ = MasterFault::none;
  DriveRequest request_ = DriveRequest::disabled;
  std::int32_t target_counts_ = 0;
  std::uint16_t controlword_ = 0;
  double last_heartbeat_s_ = 0.0, heartbeat_lost_at_s_ = 0.0;
  bool heartbeat_lost_ = false;
  bool started_ = false, boot_seen_ = false, tpdo1_seen_ = false, sync_sent_ = false;
  bool first_cycle_ = true;
  int missed_in_row_ = 0;
};

}  // namespace maglead::canopen
