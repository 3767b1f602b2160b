#include "maglead/canopen/master.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace maglead::canopen {
namespace {

// CiA 402's device type: the profile number in the low 16 bits of 0x1000.
constexpr std::uint32_t cia402_profile = 402;
constexpr std::int8_t mode_cyclic_sync_position = 8;
constexpr std::uint32_t pdo_disabled_bit = 0x80000000U;
constexpr std::uint8_t transmission_every_sync = 1;
constexpr std::uint32_t abort_no_object = 0x06020000;

std::string hex(std::uint32_t value, int digits) {
  std::array<char, 16> text{};
  std::snprintf(text.data(), text.size(), "0x%0*X", digits, value);
  return text.data();
}

std::string object_name(std::uint16_t index, std::uint8_t sub) {
  return "object " + hex(index, 4) + ":" + hex(sub, 2).substr(2);
}

}  // namespace

const char* master_fault_text(MasterFault fault) noexcept {
  switch (fault) {
    case MasterFault::none:
      return "no fault";
    case MasterFault::heartbeat_lost:
      return "drive silent: no heartbeat within its timeout";
    case MasterFault::pdo_timeout:
      return "drive stopped sending its process data (TPDO)";
    case MasterFault::drive_fault:
      return "the drive reports a fault";
    case MasterFault::bus_off:
      return "CAN controller bus-off";
    case MasterFault::drive_restarted:
      return "the drive restarted (boot-up while running)";
  }
  return "unknown fault";
}

std::string describe_identity(const DriveIdentity& id) {
  return "vendor " + hex(id.vendor_id, 8) + ", product " + hex(id.product_code, 8) + ", revision " +
         hex(id.revision, 8) + ", serial " + hex(id.serial, 8) +
         (id.device_name.empty() ? "" : ", \"" + id.device_name + "\"");
}

Cia402Master::Cia402Master(CanBus& bus, DriveConfig config)
    : bus_(bus),
      cfg_(config),
      sdo_(bus, config.node_id, config.sdo_timeout_s),
      rpdo1_(rpdo1_map()),
      tpdo1_(tpdo1_map()),
      tpdo2_(tpdo2_map(config)) {
  check_drive_config(cfg_);
  sdo_.on_other_frame([this](const CanFrame& f) { handle_frame(f, bus_.now_s()); });
}

SdoResult Cia402Master::upload(std::uint16_t index, std::uint8_t sub,
                               std::vector<std::uint8_t>& data) {
  SdoResult r;
  for (int attempt = 0; attempt < cfg_.sdo_attempts; ++attempt) {
    if (attempt > 0) ++counters_.sdo_retries;
    r = sdo_.upload(index, sub, data);
    if (r.status != SdoStatus::timeout) break;
  }
  return r;
}

/// After every attempt timed out, what to check: frames are lost or the drive does not answer.
std::string Cia402Master::timeout_advice(const SdoResult& r) const {
  if (r.status != SdoStatus::timeout) return "";
  char b[200];
  std::snprintf(b, sizeof b,
                " (no answer within %g s on any of %d attempts, sdo_timeout_s and sdo_attempts in "
                "drive.toml: the bus loses frames or the node does not answer)",
                cfg_.sdo_timeout_s, cfg_.sdo_attempts);
  return b;
}

std::vector<std::uint8_t> Cia402Master::read(std::uint16_t index, std::uint8_t sub) {
  std::vector<std::uint8_t> data;
  const SdoResult r = upload(index, sub, data);
  if (!r.ok())
    throw std::runtime_error("drive node " + std::to_string(cfg_.node_id) + ": " +
                             describe_sdo(r, true, index, sub) + timeout_advice(r));
  return data;
}

void Cia402Master::write_checked(std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                                 std::size_t bytes) {
  std::array<std::uint8_t, 4> data{};
  put_le(data.data(), bytes, value);
  SdoResult r;
  for (int attempt = 0; attempt < cfg_.sdo_attempts; ++attempt) {
    if (attempt > 0) ++counters_.sdo_retries;
    r = sdo_.download(index, sub, std::span(data.data(), bytes));
    if (r.status != SdoStatus::timeout) break;
  }
  const std::string node = "drive node " + std::to_string(cfg_.node_id) + ": ";
  if (!r.ok())
    throw std::runtime_error(node + describe_sdo(r, false, index, sub) + timeout_advice(r));
  const std::vector<std::uint8_t> back = read(index, sub);
  const std::uint32_t mask = bytes == 4 ? 0xFFFFFFFFU : (1U << (8 * bytes)) - 1U;
  const std::uint32_t got = back.size() == bytes ? get_le(back.data(), bytes) : ~value;
  if ((got & mask) != (value & mask))
    throw std::runtime_error(node + object_name(index, sub) + " reads back " +
                             (back.size() == bytes ? hex(got, 2 * static_cast<int>(bytes))
                                                   : std::to_string(back.size()) + " bytes") +
                             " after writing " + hex(value & mask, 2 * static_cast<int>(bytes)) +
                             ": the drive did not take the configuration");
}

void Cia402Master::await_boot_up() {
  const double deadline_s = bus_.now_s() + cfg_.boot_timeout_s;
  CanFrame f;
  boot_seen_ = false;
  while (!boot_seen_) {
    const CanStatus s = bus_.receive(f, deadline_s);
    if (s == CanStatus::timeout) {
      char b[200];
      std::snprintf(b, sizeof b,
                    "drive node %d: no boot-up message within %g s of NMT reset communication (is "
                    "it powered, on this bus, at this node id and bit rate?)",
                    static_cast<int>(cfg_.node_id), cfg_.boot_timeout_s);
      throw std::runtime_error(b);
    }
    if (s == CanStatus::ok) handle_frame(f, bus_.now_s());
  }
}

void Cia402Master::read_identity() {
  const auto u32 = [this](std::uint16_t index, std::uint8_t sub) {
    const std::vector<std::uint8_t> d = read(index, sub);
    return get_le(d.data(), std::min<std::size_t>(d.size(), 4));
  };
  identity_.device_type = u32(0x1000, 0);
  if ((identity_.device_type & 0xFFFFU) != cia402_profile)
    throw std::runtime_error("drive node " + std::to_string(cfg_.node_id) + ": device type " +
                             hex(identity_.device_type, 8) + " is not a CiA 402 drive");
  identity_.vendor_id = u32(0x1018, 1);
  identity_.product_code = u32(0x1018, 2);
  identity_.revision = u32(0x1018, 3);
  identity_.serial = u32(0x1018, 4);
  // 0x1008 is optional in CiA 301: a drive without it has no name to print, no more. Nor does
  // one whose name was lost on every attempt: the node answered the identity just before, and
  // a start-up is not refused for a name.
  std::vector<std::uint8_t> name;
  const SdoResult r = upload(0x1008, 0, name);
  if (r.ok())
    identity_.device_name.assign(name.begin(), name.end());
  else if (r.abort_code != abort_no_object && r.status != SdoStatus::timeout)
    throw std::runtime_error("drive node " + std::to_string(cfg_.node_id) + ": " +
                             describe_sdo(r, true, 0x1008, 0) + timeout_advice(r));
}

void Cia402Master::configure_pdo(std::uint16_t comm_index, std::uint32_t cob_id,
                                 const PdoMap& map) {
  // CiA 301's order: disable the PDO, clear its mapping, map, set the count, enable.
  const auto map_index = static_cast<std::uint16_t>(comm_index + 0x200);
  write_checked(comm_index, 1, cob_id | pdo_disabled_bit, 4);
  write_checked(comm_index, 2, transmission_every_sync, 1);
  write_checked(map_index, 0, 0, 1);
  for (std::size_t i = 0; i < map.count; ++i)
    write_checked(map_index, static_cast<std::uint8_t>(i + 1), map.entries[i].mapping_value(), 4);
  write_checked(map_index, 0, static_cast<std::uint32_t>(map.count), 1);
  write_checked(comm_index, 1, cob_id, 4);
}

void Cia402Master::start() {
  started_ = false;
  fault_ = MasterFault::none;
  (void)bus_.send(nmt_frame(NmtCommand::reset_communication, cfg_.node_id));
  await_boot_up();
  read_identity();
  std::uint8_t period = 0;
  std::int8_t exponent = 0;
  interpolation_period_code(cfg_.loop_period_s, period, exponent);
  write_checked(0x6060, 0, static_cast<std::uint8_t>(mode_cyclic_sync_position), 1);
  write_checked(0x60C2, 1, period, 1);
  write_checked(0x60C2, 2, static_cast<std::uint8_t>(exponent), 1);
  write_checked(0x1017, 0, static_cast<std::uint32_t>(std::lround(cfg_.heartbeat_producer_s * 1e3)),
                2);
  configure_pdo(0x1400, cob_rpdo1 + cfg_.node_id, rpdo1_);
  configure_pdo(0x1800, cob_tpdo1 + cfg_.node_id, tpdo1_);
  configure_pdo(0x1801, cob_tpdo2 + cfg_.node_id, tpdo2_);
  // The drive's mode display 0x6061 confirms the mode is in force, not only stored.
  const std::vector<std::uint8_t> shown = read(0x6061, 0);
  if (shown.size() != 1 || static_cast<std::int8_t>(shown[0]) != mode_cyclic_sync_position)
    throw std::runtime_error("drive node " + std::to_string(cfg_.node_id) +
                             ": object 0x6061:00 (mode display) does not show cyclic "
                             "synchronous position after writing 0x6060");
  (void)bus_.send(nmt_frame(NmtCommand::start, cfg_.node_id));
  last_heartbeat_s_ = bus_.now_s();
  tpdo1_seen_ = sync_sent_ = heartbeat_lost_ = false;
  first_cycle_ = true;
  missed_in_row_ = 0;
  started_ = true;
}

void Cia402Master::latch(MasterFault fault) noexcept {
  if (fault_ == MasterFault::none) fault_ = fault;
}

void Cia402Master::take_pdo(const CanFrame& frame) noexcept {
  std::array<std::uint32_t, 4> v{};
  if (frame.id == cob_tpdo1 + cfg_.node_id &&
      unpack_pdo(tpdo1_, frame, std::span(v.data(), tpdo1_.count))) {
    feedback_.statusword = static_cast<std::uint16_t>(v[0]);
    feedback_.state = decode_statusword(feedback_.statusword);
    feedback_.position_counts = static_cast<std::int32_t>(v[1]);
    feedback_.error_code = static_cast<std::uint16_t>(v[2]);
    tpdo1_seen_ = true;
  } else if (frame.id == cob_tpdo2 + cfg_.node_id &&
             unpack_pdo(tpdo2_, frame, std::span(v.data(), tpdo2_.count))) {
    feedback_.second_encoder_counts = static_cast<std::int32_t>(v[0]);
  }
}

void Cia402Master::handle_frame(const CanFrame& frame, double now_s) noexcept {
  if (frame.id == cob_heartbeat + cfg_.node_id && frame.len >= 1) {
    feedback_.nmt = nmt_state_of(frame.data[0]);
    last_heartbeat_s_ = now_s;
    if (feedback_.nmt == NmtState::boot_up) {
      boot_seen_ = true;
      if (started_) latch(MasterFault::drive_restarted);
    }
  } else if (frame.id == cob_emcy + cfg_.node_id && frame.len == 8) {
    const Emergency e = decode_emergency(frame);
    if (e.error_code != 0) {
      last_emcy_ = e;
      ++counters_.emergencies;
    }
  } else {
    take_pdo(frame);
  }
}

void Cia402Master::supervise(double now_s) noexcept {
  if (now_s - last_heartbeat_s_ > cfg_.heartbeat_timeout_s) {
    if (!heartbeat_lost_) heartbeat_lost_at_s_ = now_s;
    heartbeat_lost_ = true;
    latch(MasterFault::heartbeat_lost);
  }
  if (sync_sent_) {
    if (tpdo1_seen_) {
      missed_in_row_ = 0;
    } else {
      ++counters_.missed_tpdo;
      if (++missed_in_row_ >= cfg_.max_missed_cycles) latch(MasterFault::pdo_timeout);
    }
  }
  tpdo1_seen_ = false;
}

MasterFault Cia402Master::fault() const noexcept {
  if (fault_ != MasterFault::none) return fault_;
  const bool drive_fault =
      feedback_.state == DriveState::fault || feedback_.state == DriveState::fault_reaction_active;
  return drive_fault ? MasterFault::drive_fault : MasterFault::none;
}

void Cia402Master::request(DriveRequest request) noexcept {
  request_ = request;
  // A reset clears the master's own latch once its cause is gone; the drive's fault clears
  // through the controlword sequence.
  if (request == DriveRequest::fault_reset) {
    sequencer_.restart_fault_reset();
    fault_ = MasterFault::none;
    heartbeat_lost_ = false;
    missed_in_row_ = 0;
  }
}

MasterFault Cia402Master::cycle(double now_s) noexcept {
  receive(now_s);
  return transmit();
}

MasterFault Cia402Master::receive(double now_s) noexcept {
  ++counters_.cycles;
  // The loop's clock need not be the bus's: the heartbeat is timed from the first cycle on.
  if (first_cycle_) last_heartbeat_s_ = now_s;
  first_cycle_ = false;
  CanFrame f;
  for (;;) {
    const CanStatus s = bus_.receive(f, now_s);
    if (s == CanStatus::timeout) break;
    if (s == CanStatus::ok) handle_frame(f, now_s);
    if (s == CanStatus::error_frame) ++counters_.error_frames;
    if (s == CanStatus::bus_off) latch(MasterFault::bus_off);
    if (s == CanStatus::io_error) break;
  }
  if (started_) supervise(now_s);
  return fault();
}

MasterFault Cia402Master::transmit() noexcept {
  // A master-side fault stops the axis: quick stop until the controller asks for a reset.
  const bool stop = fault_ != MasterFault::none;
  controlword_ = sequencer_.next(feedback_.state, stop ? DriveRequest::quick_stop : request_);
  // Bumpless: until the drive is enabled the target is where the motor is, so the first
  // enabled cycle commands no jump whatever was set before.
  if (feedback_.state != DriveState::operation_enabled) target_counts_ = feedback_.position_counts;
  const std::array<std::uint32_t, 2> rpdo{controlword_, static_cast<std::uint32_t>(target_counts_)};
  CanFrame out;
  out.id = cob_rpdo1 + cfg_.node_id;
  pack_pdo(rpdo1_, rpdo, out);
  // The RPDO before SYNC: a synchronous RPDO takes effect at the SYNC that follows it.
  if (bus_.send(out) == CanStatus::tx_busy) ++counters_.tx_busy;
  if (bus_.send(sync_frame()) == CanStatus::tx_busy) ++counters_.tx_busy;
  sync_sent_ = started_;
  return fault();
}

const char* Cia402Master::alarm_text() const noexcept {
  const MasterFault f = fault();
  if (f != MasterFault::drive_fault) return master_fault_text(f);
  // An EMCY is unconfirmed and may be lost; 0x603F in the TPDO says the same every cycle.
  if (feedback_.error_code != 0) return emergency_text(feedback_.error_code);
  if (last_emcy_.error_code != 0) return emergency_text(last_emcy_.error_code);
  return master_fault_text(f);
}

}  // namespace maglead::canopen
