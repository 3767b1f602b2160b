#pragma once
// A simulated CiA 402 servo drive on the virtual CAN bus, written from CiA 301 and CiA 402
// rather than from the master: its own object dictionary, SDO server, NMT state machine,
// heartbeat producer and device state machine, and its own reading of the controlword. On each
// SYNC in operation enabled it applies the RPDO's target position to the wrapped simulated
// actuator, steps it to the SYNC's time and sends its TPDOs. Faults are injected on purpose: a
// drive fault with its EMCY, a late TPDO, a write it acknowledges but ignores (dropped frames
// and a silent drive are the bus's to inject).
#include <cstdint>
#include <string>
#include <vector>

#include "maglead/canopen/can_bus.hpp"
#include "maglead/canopen/virtual_bus.hpp"
#include "maglead/plant/simulated_actuator.hpp"

namespace maglead::canopen {

struct SimulatedDriveOptions {
  std::uint8_t node_id = 1;
  double counts_per_motor_turn = 4096;  // the drive's position unit
  std::uint16_t second_encoder_index = 0x60E4;
  std::uint8_t second_encoder_sub = 1;
  std::uint32_t vendor_id = 0x000000FB;  // Maxon's CiA vendor id, as the EPOS4 reports it
  std::uint32_t product_code = 0x64000000, revision = 0x01000000, serial = 0x00C1A402;
  // A drive's fault reaction (ramp down, open the brake) takes a moment before it shows fault.
  double fault_reaction_s = 2e-3;
};

class SimulatedCia402Drive final : public VirtualDevice {
 public:
  /// Attaches to `bus` as node options.node_id and registers itself for polling.
  SimulatedCia402Drive(VirtualCanBus& bus, SimulatedActuator& actuator,
                       SimulatedDriveOptions options = {});
  void poll(double now_s) noexcept override;

  // Fault injection.
  /// From `at_s`: fault reaction, then fault; EMCY with `error_code`; 0x603F shows it. A fault
  /// reset clears it (the cause is taken as gone).
  void inject_fault(std::uint16_t error_code, double at_s) noexcept;
  /// The TPDOs answering the first SYNC at or after `at_s` go out `late_s` late.
  void delay_tpdo(double at_s, double late_s) noexcept;
  /// The following error window 0x6065 [counts] and time out 0x6066 [ms], as a drive's set-up
  /// tool writes them (the master does not); 0xFFFFFFFF switches the check off (the default).
  void set_following_error_window(std::uint32_t window_counts, std::uint16_t timeout_ms) noexcept;
  /// SDO writes to this object are acknowledged but not stored (a drive that ignores them).
  void ignore_writes_to(std::uint16_t index, std::uint8_t sub) noexcept;

  /// What the drive's own statusword 0x6041 holds now (for tests).
  std::uint16_t statusword() const noexcept;
  std::uint8_t nmt_state() const noexcept { return nmt_; }
  std::int32_t target_counts() const noexcept;

  enum class Access : std::uint8_t { ro, rw, wo };
  enum class Pdo : std::uint8_t { none, rx, tx };
  struct Entry {
    std::uint16_t index;
    std::uint8_t sub;
    std::uint8_t bytes;  // 1, 2, 4; 0 for a string or domain (stored in `text`)
    Access access;
    Pdo pdo;
    std::uint32_t value;
    std::string text;
  };

 private:
  enum class Power : std::uint8_t {
    not_ready,
    switch_on_disabled,
    ready,
    switched_on,
    enabled,
    quick_stop,
    fault_reaction,
    fault,
  };
  void build_dictionary();
  void reset_communication() noexcept;
  void on_frame(const CanFrame& frame, double now_s) noexcept;
  void on_nmt(const CanFrame& frame) noexcept;
  void on_sync(double now_s) noexcept;
  void on_rpdo(const CanFrame& frame) noexcept;
  void send_tpdos(double now_s) noexcept;
  void device_control(double now_s) noexcept;
  void step_actuator(double now_s) noexcept;
  void check_following_error(bool follow, double actual_counts, double now_s) noexcept;
  void enter_fault(std::uint16_t error_code, double now_s) noexcept;
  void emergency(std::uint16_t error_code) noexcept;
  void heartbeat() noexcept;

  // SDO server
  void on_sdo(const CanFrame& request) noexcept;
  void sdo_initiate_download(const CanFrame& request) noexcept;
  void sdo_download_segment(const CanFrame& request) noexcept;
  void sdo_initiate_upload(const CanFrame& request) noexcept;
  void sdo_upload_segment(const CanFrame& request) noexcept;
  void sdo_answer(std::uint8_t command, std::uint16_t index, std::uint8_t sub,
                  std::uint32_t value) noexcept;
  void sdo_abort(std::uint16_t index, std::uint8_t sub, std::uint32_t code) noexcept;
  std::uint32_t check_write(const Entry& entry, std::uint32_t value) const noexcept;
  std::uint32_t check_mapping(std::uint16_t map_index, std::uint32_t count) const noexcept;
  void store(Entry& entry, std::uint32_t value) noexcept;

  Entry* find(std::uint16_t index, std::uint8_t sub) noexcept;
  const Entry* find(std::uint16_t index, std::uint8_t sub) const noexcept;
  bool has_index(std::uint16_t index) const noexcept;
  std::uint32_t get(std::uint16_t index, std::uint8_t sub) const noexcept;
  void set(std::uint16_t index, std::uint8_t sub, std::uint32_t value) noexcept;
  bool pdo_valid(std::uint16_t comm_index) const noexcept;

  VirtualCanPort& port_;
  SimulatedActuator& actuator_;
  SimulatedDriveOptions opt_;
  std::vector<Entry> od_;
  std::uint8_t nmt_ = 0x00;  // heartbeat byte: 0x00 initialising, 0x7F, 0x05, 0x04
  bool boot_pending_ = true;
  double next_heartbeat_s_ = 0.0;
  Power power_ = Power::not_ready;
  bool fault_reset_bit_ = false;
  // Following error (CiA 402, cyclic synchronous position): the demand the servo had a cycle to
  // reach, and since when the actual position has been outside the window.
  double demand_counts_ = 0.0;
  double outside_since_s_ = -1.0;
  bool following_error_ = false;
  std::uint16_t pending_error_ = 0;
  double fault_at_s_ = -1.0, fault_reaction_until_s_ = 0.0;
  CanFrame rpdo_{};
  bool rpdo_pending_ = false;
  double late_at_s_ = -1.0, late_s_ = 0.0;
  std::array<CanFrame, 2> late_frames_{};
  std::size_t late_count_ = 0;
  double late_send_s_ = 0.0;
  std::uint16_t ignored_index_ = 0;
  std::uint8_t ignored_sub_ = 0;
  // SDO server state: one segmented transfer at a time.
  enum class Transfer : std::uint8_t { idle, download, upload } transfer_ = Transfer::idle;
  std::uint16_t transfer_index_ = 0;
  std::uint8_t transfer_sub_ = 0, toggle_ = 0;
  std::size_t transfer_size_ = 0, transfer_at_ = 0;
  std::string transfer_data_;
};

}  // namespace maglead::canopen
