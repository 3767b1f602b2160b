#include "maglead/canopen/simulated_drive.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace maglead::canopen {
namespace {

// CiA 301 as the drive reads it (kept apart from the master's constants on purpose).
constexpr std::uint32_t fn_sync = 0x080, fn_emcy = 0x080, fn_tpdo1 = 0x180, fn_rpdo1 = 0x200,
                        fn_tpdo2 = 0x280, fn_sdo_answer = 0x580, fn_sdo_request = 0x600,
                        fn_heartbeat = 0x700;
constexpr std::uint8_t nmt_pre_operational = 0x7F, nmt_operational = 0x05, nmt_stopped = 0x04;
constexpr std::uint32_t cob_invalid = 0x80000000U;
constexpr std::uint32_t ab_toggle = 0x05030000, ab_command = 0x05040001, ab_read_only = 0x06010002,
                        ab_write_only = 0x06010001, ab_no_object = 0x06020000,
                        ab_not_mappable = 0x06040041, ab_pdo_too_long = 0x06040042,
                        ab_length = 0x06070010, ab_length_high = 0x06070012,
                        ab_length_low = 0x06070013, ab_no_sub = 0x06090011, ab_value = 0x06090030,
                        ab_too_high = 0x06090031, ab_state = 0x08000022;
// 0x1000: device profile 402 in the low word, "servo drive" (0x0002) in the high word.
constexpr std::uint32_t device_type_servo = 0x00020192;
// Quick stop option code 6: ramp down and stay in quick stop active (transition 16 allowed).
constexpr std::uint32_t quick_stop_stay = 6;
// 0x6065 at its largest: the following error check is off.
constexpr std::uint32_t following_error_off = 0xFFFFFFFFU;
constexpr std::size_t max_domain_bytes = 64;  // 0x2001, the scratch domain for segmented writes

std::uint32_t le(const std::uint8_t* b, std::size_t n) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < n; ++i) v |= static_cast<std::uint32_t>(b[i]) << (8 * i);
  return v;
}

}  // namespace

SimulatedCia402Drive::SimulatedCia402Drive(VirtualCanBus& bus, SimulatedActuator& actuator,
                                           SimulatedDriveOptions options)
    : port_(bus.attach(options.node_id)), actuator_(actuator), opt_(options) {
  build_dictionary();
  transfer_data_.reserve(max_domain_bytes);
  bus.add_device(*this);
}

void SimulatedCia402Drive::build_dictionary() {
  using A = Access;
  using P = Pdo;
  const std::uint8_t n = opt_.node_id;
  od_ = {
      {0x1000, 0, 4, A::ro, P::none, device_type_servo, {}},
      {0x1008, 0, 0, A::ro, P::none, 0, "maglead simulated CiA 402 drive"},
      {0x1017, 0, 2, A::rw, P::none, 0, {}},
      {0x1018, 0, 1, A::ro, P::none, 4, {}},
      {0x1018, 1, 4, A::ro, P::none, opt_.vendor_id, {}},
      {0x1018, 2, 4, A::ro, P::none, opt_.product_code, {}},
      {0x1018, 3, 4, A::ro, P::none, opt_.revision, {}},
      {0x1018, 4, 4, A::ro, P::none, opt_.serial, {}},
      {0x2001, 0, 0, A::rw, P::none, 0, {}},
  };
  // Communication and mapping of RPDO1, TPDO1, TPDO2 with the predefined connection set's ids.
  const std::array<std::pair<std::uint16_t, std::uint32_t>, 3> pdos{
      {{0x1400, fn_rpdo1 + n}, {0x1800, fn_tpdo1 + n}, {0x1801, fn_tpdo2 + n}}};
  for (const auto& [comm, cob] : pdos) {
    od_.push_back({comm, 0, 1, A::ro, P::none, 2, {}});
    od_.push_back({comm, 1, 4, A::rw, P::none, cob, {}});
    od_.push_back({comm, 2, 1, A::rw, P::none, 255, {}});
    const auto map = static_cast<std::uint16_t>(comm + 0x200);
    od_.push_back({map, 0, 1, A::rw, P::none, 0, {}});
    for (std::uint8_t s = 1; s <= 4; ++s) od_.push_back({map, s, 4, A::rw, P::none, 0, {}});
  }
  const std::vector<Entry> device{
      {0x603F, 0, 2, A::ro, P::tx, 0, {}},
      {0x6040, 0, 2, A::rw, P::rx, 0, {}},
      {0x6041, 0, 2, A::ro, P::tx, 0, {}},
      {0x605A, 0, 2, A::ro, P::none, quick_stop_stay, {}},
      {0x6060, 0, 1, A::rw, P::none, 0, {}},
      {0x6061, 0, 1, A::ro, P::tx, 0, {}},
      {0x6064, 0, 4, A::ro, P::tx, 0, {}},
      {0x607A, 0, 4, A::rw, P::rx, 0, {}},
      {0x6065, 0, 4, A::rw, P::none, following_error_off, {}},
      {0x6066, 0, 2, A::rw, P::none, 10, {}},
      {0x60C2, 0, 1, A::ro, P::none, 2, {}},
      {0x60C2, 1, 1, A::rw, P::none, 1, {}},
      {0x60C2, 2, 1, A::rw, P::none, 0xFD, {}},  // 1·10^-3 s
  };
  od_.insert(od_.end(), device.begin(), device.end());
  if (opt_.second_encoder_sub > 0)
    od_.push_back({opt_.second_encoder_index, 0, 1, A::ro, P::none, opt_.second_encoder_sub, {}});
  od_.push_back({opt_.second_encoder_index, opt_.second_encoder_sub, 4, A::ro, P::tx, 0, {}});
}

SimulatedCia402Drive::Entry* SimulatedCia402Drive::find(std::uint16_t index,
                                                        std::uint8_t sub) noexcept {
  for (Entry& e : od_)
    if (e.index == index && e.sub == sub) return &e;
  return nullptr;
}
const SimulatedCia402Drive::Entry* SimulatedCia402Drive::find(std::uint16_t index,
                                                              std::uint8_t sub) const noexcept {
  for (const Entry& e : od_)
    if (e.index == index && e.sub == sub) return &e;
  return nullptr;
}
bool SimulatedCia402Drive::has_index(std::uint16_t index) const noexcept {
  return std::any_of(od_.begin(), od_.end(), [index](const Entry& e) { return e.index == index; });
}
std::uint32_t SimulatedCia402Drive::get(std::uint16_t index, std::uint8_t sub) const noexcept {
  const Entry* e = find(index, sub);
  return e != nullptr ? e->value : 0;
}
void SimulatedCia402Drive::set(std::uint16_t index, std::uint8_t sub,
                               std::uint32_t value) noexcept {
  if (Entry* e = find(index, sub)) e->value = value;
}
bool SimulatedCia402Drive::pdo_valid(std::uint16_t comm_index) const noexcept {
  return (get(comm_index, 1) & cob_invalid) == 0;
}

void SimulatedCia402Drive::inject_fault(std::uint16_t error_code, double at_s) noexcept {
  pending_error_ = error_code;
  fault_at_s_ = at_s;
}
void SimulatedCia402Drive::delay_tpdo(double at_s, double late_s) noexcept {
  late_at_s_ = at_s;
  late_s_ = late_s;
}
void SimulatedCia402Drive::ignore_writes_to(std::uint16_t index, std::uint8_t sub) noexcept {
  ignored_index_ = index;
  ignored_sub_ = sub;
}
std::int32_t SimulatedCia402Drive::target_counts() const noexcept {
  return static_cast<std::int32_t>(get(0x607A, 0));
}

void SimulatedCia402Drive::reset_communication() noexcept {
  // Communication objects back to their defaults: the predefined connection set, no heartbeat.
  const std::uint8_t n = opt_.node_id;
  set(0x1017, 0, 0);
  set(0x1400, 1, fn_rpdo1 + n);
  set(0x1800, 1, fn_tpdo1 + n);
  set(0x1801, 1, fn_tpdo2 + n);
  for (const std::uint16_t comm : std::array<std::uint16_t, 3>{0x1400, 0x1800, 0x1801}) {
    set(comm, 2, 255);
    for (std::uint8_t s = 0; s <= 4; ++s) set(static_cast<std::uint16_t>(comm + 0x200), s, 0);
  }
  transfer_ = Transfer::idle;
  rpdo_pending_ = false;
  nmt_ = 0x00;
  boot_pending_ = true;
}

void SimulatedCia402Drive::heartbeat() noexcept {
  CanFrame f;
  f.id = fn_heartbeat + opt_.node_id;
  f.len = 1;
  f.data[0] = nmt_;
  (void)port_.send(f);
}

void SimulatedCia402Drive::poll(double now_s) noexcept {
  if (boot_pending_) {  // initialisation done: the boot-up message, then pre-operational
    heartbeat();
    boot_pending_ = false;
    nmt_ = nmt_pre_operational;
    next_heartbeat_s_ = now_s;
    if (power_ == Power::not_ready) power_ = Power::switch_on_disabled;  // transition 1
  }
  CanFrame f;
  while (port_.receive(f, now_s) == CanStatus::ok) on_frame(f, now_s);
  if (fault_at_s_ >= 0.0 && now_s >= fault_at_s_) {
    fault_at_s_ = -1.0;
    enter_fault(pending_error_, now_s);
  }
  if (power_ == Power::fault_reaction && now_s >= fault_reaction_until_s_)
    power_ = Power::fault;  // transition 14
  set(0x6041, 0, statusword());
  if (late_count_ > 0 && now_s >= late_send_s_) {
    for (std::size_t i = 0; i < late_count_; ++i) (void)port_.send(late_frames_[i]);
    late_count_ = 0;
  }
  const std::uint32_t period_ms = get(0x1017, 0);
  if (period_ms > 0 && now_s >= next_heartbeat_s_ + 1e-3 * period_ms) {
    next_heartbeat_s_ += 1e-3 * period_ms;
    if (next_heartbeat_s_ + 1e-3 * period_ms < now_s) next_heartbeat_s_ = now_s;
    heartbeat();
  }
}

void SimulatedCia402Drive::on_frame(const CanFrame& f, double now_s) noexcept {
  if (f.id == 0x000) {
    on_nmt(f);
  } else if (f.id == fn_sdo_request + opt_.node_id && f.len == 8) {
    if (nmt_ == nmt_pre_operational || nmt_ == nmt_operational) on_sdo(f);
  } else if (f.id == fn_sync) {
    if (nmt_ == nmt_operational) on_sync(now_s);
  } else if (nmt_ == nmt_operational && pdo_valid(0x1400) && f.id == (get(0x1400, 1) & 0x7FF)) {
    on_rpdo(f);
  }
}

void SimulatedCia402Drive::on_nmt(const CanFrame& f) noexcept {
  if (f.len < 2 || (f.data[1] != 0 && f.data[1] != opt_.node_id)) return;
  switch (f.data[0]) {
    case 0x01:
      nmt_ = nmt_operational;
      break;
    case 0x02:
      nmt_ = nmt_stopped;
      break;
    case 0x80:
      nmt_ = nmt_pre_operational;
      break;
    case 0x81:  // reset node: the application too
      power_ = Power::not_ready;
      set(0x6060, 0, 0);
      set(0x6061, 0, 0);
      reset_communication();
      break;
    case 0x82:
      reset_communication();
      break;
    default:
      break;
  }
}

void SimulatedCia402Drive::on_rpdo(const CanFrame& f) noexcept {
  // A synchronous RPDO (type 0..240) waits for the next SYNC; others act at once.
  rpdo_ = f;
  rpdo_pending_ = true;
}

void SimulatedCia402Drive::on_sync(double now_s) noexcept {
  if (rpdo_pending_) {
    rpdo_pending_ = false;
    std::size_t mapped_bytes = 0;
    const auto entries = static_cast<std::uint8_t>(get(0x1600, 0));
    for (std::uint8_t s = 1; s <= entries; ++s) mapped_bytes += (get(0x1600, s) & 0xFFU) / 8U;
    // A PDO shorter than its mapping is not processed (CiA 301); the last values stand.
    std::size_t at = 0;
    for (std::uint8_t s = 1; s <= entries && mapped_bytes <= rpdo_.len; ++s) {
      const std::uint32_t m = get(0x1600, s);
      const std::size_t bytes = (m & 0xFFU) / 8U;
      set(static_cast<std::uint16_t>(m >> 16), static_cast<std::uint8_t>(m >> 8),
          le(rpdo_.data.data() + at, bytes));
      at += bytes;
    }
  }
  device_control(now_s);
  step_actuator(now_s);
  set(0x6041, 0, statusword());
  send_tpdos(now_s);
}

std::uint16_t SimulatedCia402Drive::statusword() const noexcept {
  // CiA 402 state coding, with "voltage enabled" (bit 4) where the power stage is on, "quick
  // stop" (bit 5) high unless a quick stop is active, and "remote" (bit 9): run by the network.
  constexpr std::uint16_t voltage = 1U << 4, no_quick_stop = 1U << 5, remote = 1U << 9;
  std::uint16_t sw = 0;
  switch (power_) {
    case Power::not_ready:
      sw = 0x0000;
      break;
    case Power::switch_on_disabled:
      sw = 0x0040;
      break;
    case Power::ready:
      sw = 0x0001 | voltage | no_quick_stop;
      break;
    case Power::switched_on:
      sw = 0x0003 | voltage | no_quick_stop;
      break;
    case Power::enabled:
      sw = 0x0007 | voltage | no_quick_stop;
      break;
    case Power::quick_stop:
      sw = 0x0007 | voltage;
      break;
    case Power::fault_reaction:
      sw = 0x000F | voltage;
      break;
    case Power::fault:
      sw = 0x0008;
      break;
  }
  constexpr std::uint16_t following_error = 1U << 13;
  if (following_error_ && power_ == Power::enabled) sw |= following_error;
  return static_cast<std::uint16_t>(sw | remote);
}

void SimulatedCia402Drive::device_control(double now_s) noexcept {
  const auto cw = static_cast<std::uint16_t>(get(0x6040, 0));
  const bool reset_edge = (cw & 0x80U) != 0 && !fault_reset_bit_;
  fault_reset_bit_ = (cw & 0x80U) != 0;
  if (power_ == Power::fault) {
    if (reset_edge) {  // transition 15: the injected cause is taken as cleared
      power_ = Power::switch_on_disabled;
      set(0x603F, 0, 0);
      emergency(0x0000);  // CiA 301: an EMCY with code 0 says the error is reset
    }
    return;
  }
  if (power_ == Power::fault_reaction || power_ == Power::not_ready || (cw & 0x80U) != 0) return;
  // The command, read from bits 0..3 as CiA 402's table of device control commands has it.
  const bool voltage = (cw & 0x02U) != 0, no_quick_stop = (cw & 0x04U) != 0;
  const bool switch_on = (cw & 0x01U) != 0, operate = (cw & 0x08U) != 0;
  (void)now_s;
  if (!voltage) {  // disable voltage: transitions 7, 9, 10, 12
    power_ = Power::switch_on_disabled;
    return;
  }
  if (!no_quick_stop) {  // quick stop: transitions 7, 10 to disabled, 11 to quick stop active
    if (power_ == Power::ready || power_ == Power::switched_on)
      power_ = Power::switch_on_disabled;
    else if (power_ == Power::enabled)
      power_ = Power::quick_stop;
    return;
  }
  if (!switch_on) {  // shutdown: transitions 2, 6, 8
    if (power_ == Power::switch_on_disabled || power_ == Power::switched_on ||
        power_ == Power::enabled)
      power_ = Power::ready;
    return;
  }
  if (power_ == Power::ready)
    power_ = operate ? Power::enabled : Power::switched_on;  // 3 (+4)
  else if ((power_ == Power::switched_on || power_ == Power::quick_stop) && operate)
    power_ = Power::enabled;  // 4, 16
  else if (power_ == Power::enabled && !operate)
    power_ = Power::switched_on;  // 5
}

void SimulatedCia402Drive::step_actuator(double now_s) noexcept {
  SensorSample s;
  (void)actuator_.read_sensors(now_s, s);
  const double plant_counts_per_turn = actuator_.params().actuator.motor_counts_per_rev;
  const double counts =
      static_cast<double>(s.motor_counts) * opt_.counts_per_motor_turn / plant_counts_per_turn;
  set(0x6064, 0, static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(counts))));
  set(opt_.second_encoder_index, opt_.second_encoder_sub,
      static_cast<std::uint32_t>(static_cast<std::int32_t>(s.linear_counts)));
  // Cyclic synchronous position: the target is the servo's command only with the power stage
  // enabled and the mode in force; otherwise the servo holds where the motor is.
  const bool follow = power_ == Power::enabled && get(0x6061, 0) == 8;
  check_following_error(follow, counts, now_s);
  const double target_counts =
      follow ? static_cast<double>(static_cast<std::int32_t>(get(0x607A, 0))) : counts;
  demand_counts_ = target_counts;
  (void)actuator_.write_motor_angle(2.0 * std::numbers::pi * target_counts /
                                    opt_.counts_per_motor_turn);
}

void SimulatedCia402Drive::check_following_error(bool follow, double actual_counts,
                                                 double now_s) noexcept {
  // CiA 402: the actual position outside the window around the demand for longer than the time
  // out sets statusword bit 13; it clears once the position is back inside.
  const std::uint32_t window = get(0x6065, 0);
  const bool outside = follow && window != following_error_off &&
                       std::abs(demand_counts_ - actual_counts) > static_cast<double>(window);
  if (!outside) {
    outside_since_s_ = -1.0;
    following_error_ = false;
    return;
  }
  if (outside_since_s_ < 0.0) outside_since_s_ = now_s;
  following_error_ = now_s - outside_since_s_ >= 1e-3 * get(0x6066, 0);
}

void SimulatedCia402Drive::set_following_error_window(std::uint32_t window_counts,
                                                      std::uint16_t timeout_ms) noexcept {
  set(0x6065, 0, window_counts);
  set(0x6066, 0, timeout_ms);
}

void SimulatedCia402Drive::send_tpdos(double now_s) noexcept {
  const bool late = late_at_s_ >= 0.0 && now_s >= late_at_s_;
  if (late) {
    late_at_s_ = -1.0;
    late_count_ = 0;
    late_send_s_ = now_s + late_s_;
  }
  for (const std::uint16_t comm : std::array<std::uint16_t, 2>{0x1800, 0x1801}) {
    const std::uint32_t type = get(comm, 2);
    if (!pdo_valid(comm) || type == 0 || type > 240) continue;  // only cyclic synchronous here
    const auto map = static_cast<std::uint16_t>(comm + 0x200);
    CanFrame f;
    f.id = get(comm, 1) & 0x7FFU;
    std::size_t at = 0;
    const auto entries = static_cast<std::uint8_t>(get(map, 0));
    for (std::uint8_t s = 1; s <= entries; ++s) {
      const std::uint32_t m = get(map, s);
      const std::size_t bytes = (m & 0xFFU) / 8U;
      const std::uint32_t v =
          get(static_cast<std::uint16_t>(m >> 16), static_cast<std::uint8_t>(m >> 8));
      for (std::size_t i = 0; i < bytes; ++i)
        f.data[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
      at += bytes;
    }
    f.len = static_cast<std::uint8_t>(at);
    if (late && late_count_ < late_frames_.size())
      late_frames_[late_count_++] = f;
    else
      (void)port_.send(f);
  }
}

void SimulatedCia402Drive::enter_fault(std::uint16_t error_code, double now_s) noexcept {
  power_ = Power::fault_reaction;  // transition 13
  fault_reaction_until_s_ = now_s + opt_.fault_reaction_s;
  set(0x603F, 0, error_code);
  emergency(error_code);
}

void SimulatedCia402Drive::emergency(std::uint16_t error_code) noexcept {
  CanFrame f;
  f.id = fn_emcy + opt_.node_id;
  f.len = 8;
  f.data[0] = static_cast<std::uint8_t>(error_code);
  f.data[1] = static_cast<std::uint8_t>(error_code >> 8);
  f.data[2] = error_code == 0 ? 0 : 0x01;  // error register: bit 0, generic error
  (void)port_.send(f);
}

// ------------------------------------------------------------------------------ SDO server

void SimulatedCia402Drive::sdo_answer(std::uint8_t command, std::uint16_t index, std::uint8_t sub,
                                      std::uint32_t value) noexcept {
  CanFrame f;
  f.id = fn_sdo_answer + opt_.node_id;
  f.len = 8;
  f.data[0] = command;
  f.data[1] = static_cast<std::uint8_t>(index);
  f.data[2] = static_cast<std::uint8_t>(index >> 8);
  f.data[3] = sub;
  for (std::size_t i = 0; i < 4; ++i) f.data[4 + i] = static_cast<std::uint8_t>(value >> (8 * i));
  (void)port_.send(f);
}

void SimulatedCia402Drive::sdo_abort(std::uint16_t index, std::uint8_t sub,
                                     std::uint32_t code) noexcept {
  transfer_ = Transfer::idle;
  sdo_answer(0x80, index, sub, code);
}

void SimulatedCia402Drive::on_sdo(const CanFrame& r) noexcept {
  switch (r.data[0] >> 5) {
    case 0:
      sdo_download_segment(r);
      break;
    case 1:
      sdo_initiate_download(r);
      break;
    case 2:
      sdo_initiate_upload(r);
      break;
    case 3:
      sdo_upload_segment(r);
      break;
    case 4:  // the client aborts: drop the transfer, no answer
      transfer_ = Transfer::idle;
      break;
    default:
      sdo_abort(static_cast<std::uint16_t>(le(r.data.data() + 1, 2)), r.data[3], ab_command);
  }
}

std::uint32_t SimulatedCia402Drive::check_mapping(std::uint16_t map_index,
                                                  std::uint32_t count) const noexcept {
  if (count > 4) return ab_too_high;
  const Pdo direction = map_index < 0x1800 ? Pdo::rx : Pdo::tx;
  std::uint32_t bits = 0;
  for (std::uint32_t s = 1; s <= count; ++s) {
    const std::uint32_t m = get(map_index, static_cast<std::uint8_t>(s));
    const Entry* mapped =
        find(static_cast<std::uint16_t>(m >> 16), static_cast<std::uint8_t>(m >> 8));
    if (mapped == nullptr) return ab_no_object;
    if (mapped->pdo != direction || 8U * mapped->bytes != (m & 0xFFU)) return ab_not_mappable;
    bits += m & 0xFFU;
  }
  return bits > 64 ? ab_pdo_too_long : 0;
}

std::uint32_t SimulatedCia402Drive::check_write(const Entry& e,
                                                std::uint32_t value) const noexcept {
  const std::uint16_t i = e.index;
  if (i == 0x6060) {  // the modes this drive has: profile position, velocity, homing, CSP, CSV
    const auto mode = static_cast<std::int8_t>(value);
    return mode == 1 || mode == 3 || mode == 6 || mode == 8 || mode == 9 ? 0 : ab_value;
  }
  if (i == 0x60C2 && e.sub == 2) {
    const auto exponent = static_cast<std::int8_t>(value);
    return exponent >= -6 && exponent <= 0 ? 0 : ab_value;
  }
  if (i == 0x60C2 && e.sub == 1) return value == 0 ? ab_value : 0;
  const bool comm = i == 0x1400 || i == 0x1800 || i == 0x1801;
  const bool map = i == 0x1600 || i == 0x1A00 || i == 0x1A01;
  // CiA 301: a valid PDO's id and type cannot change, nor its mapping; sub 0 gates the entries.
  if (comm && e.sub == 1 && (value & cob_invalid) == 0 && pdo_valid(i) && value != e.value)
    return ab_value;
  if (comm && e.sub == 2 && pdo_valid(i)) return ab_state;
  if (map) {
    const auto comm_index = static_cast<std::uint16_t>(i - 0x200);
    if (pdo_valid(comm_index)) return ab_state;
    if (e.sub == 0) return check_mapping(i, value);
    if (get(i, 0) != 0) return ab_state;
    if (find(static_cast<std::uint16_t>(value >> 16), static_cast<std::uint8_t>(value >> 8)) ==
        nullptr)
      return ab_no_object;
  }
  return 0;
}

void SimulatedCia402Drive::store(Entry& e, std::uint32_t value) noexcept {
  if (e.index == ignored_index_ && e.sub == ignored_sub_) return;  // injected: acknowledged only
  e.value = value;
  if (e.index == 0x6060) set(0x6061, 0, value);  // the mode is in force at once here
  if (e.index == 0x1017) next_heartbeat_s_ = port_.now_s();
}

void SimulatedCia402Drive::sdo_initiate_download(const CanFrame& r) noexcept {
  const auto index = static_cast<std::uint16_t>(le(r.data.data() + 1, 2));
  const std::uint8_t sub = r.data[3];
  Entry* e = find(index, sub);
  if (e == nullptr) return sdo_abort(index, sub, has_index(index) ? ab_no_sub : ab_no_object);
  if (e->access == Access::ro) return sdo_abort(index, sub, ab_read_only);
  const bool expedited = (r.data[0] & 0x02U) != 0, sized = (r.data[0] & 0x01U) != 0;
  if (!expedited) {  // segmented: strings and domains only here
    const std::size_t size = sized ? le(r.data.data() + 4, 4) : 0;
    if (e->bytes != 0) return sdo_abort(index, sub, ab_length);
    if (size > max_domain_bytes) return sdo_abort(index, sub, ab_length_high);
    transfer_ = Transfer::download;
    transfer_index_ = index;
    transfer_sub_ = sub;
    transfer_size_ = size;
    transfer_data_.clear();
    toggle_ = 0;
    return sdo_answer(0x60, index, sub, 0);
  }
  const std::size_t n = sized ? 4U - ((r.data[0] >> 2) & 0x03U) : 4U;
  if (e->bytes == 0) {
    e->text.assign(r.data.begin() + 4, r.data.begin() + 4 + static_cast<long>(n));
    return sdo_answer(0x60, index, sub, 0);
  }
  if (n != e->bytes) return sdo_abort(index, sub, n > e->bytes ? ab_length_high : ab_length_low);
  const std::uint32_t value = le(r.data.data() + 4, n);
  if (const std::uint32_t code = check_write(*e, value); code != 0)
    return sdo_abort(index, sub, code);
  store(*e, value);
  sdo_answer(0x60, index, sub, 0);
}

void SimulatedCia402Drive::sdo_download_segment(const CanFrame& r) noexcept {
  if (transfer_ != Transfer::download) return sdo_abort(0, 0, ab_command);
  if ((r.data[0] & 0x10U) != toggle_) return sdo_abort(transfer_index_, transfer_sub_, ab_toggle);
  const std::size_t n = 7U - ((r.data[0] >> 1) & 0x07U);
  if (transfer_data_.size() + n > max_domain_bytes)
    return sdo_abort(transfer_index_, transfer_sub_, ab_length_high);
  transfer_data_.append(r.data.begin() + 1, r.data.begin() + 1 + static_cast<long>(n));
  CanFrame answer;
  answer.id = fn_sdo_answer + opt_.node_id;
  answer.len = 8;
  answer.data[0] = static_cast<std::uint8_t>(0x20U | toggle_);
  toggle_ ^= 0x10U;
  if ((r.data[0] & 0x01U) != 0) {  // the last segment: the length must be the announced one
    transfer_ = Transfer::idle;
    if (transfer_size_ != 0 && transfer_data_.size() != transfer_size_)
      return sdo_abort(transfer_index_, transfer_sub_, ab_length);
    if (Entry* e = find(transfer_index_, transfer_sub_)) e->text = transfer_data_;
  }
  (void)port_.send(answer);
}

void SimulatedCia402Drive::sdo_initiate_upload(const CanFrame& r) noexcept {
  const auto index = static_cast<std::uint16_t>(le(r.data.data() + 1, 2));
  const std::uint8_t sub = r.data[3];
  const Entry* e = find(index, sub);
  if (e == nullptr) return sdo_abort(index, sub, has_index(index) ? ab_no_sub : ab_no_object);
  if (e->access == Access::wo) return sdo_abort(index, sub, ab_write_only);
  if (e->bytes != 0) {  // expedited, size indicated: e = s = 1, n = 4 - size
    const auto command = static_cast<std::uint8_t>(0x43U | ((4U - e->bytes) << 2));
    return sdo_answer(command, index, sub, e->value);
  }
  transfer_ = Transfer::upload;
  transfer_index_ = index;
  transfer_sub_ = sub;
  transfer_data_.assign(e->text, 0, std::min(e->text.size(), max_domain_bytes));
  transfer_at_ = 0;
  toggle_ = 0;
  sdo_answer(0x41, index, sub, static_cast<std::uint32_t>(transfer_data_.size()));
}

void SimulatedCia402Drive::sdo_upload_segment(const CanFrame& r) noexcept {
  if (transfer_ != Transfer::upload) return sdo_abort(0, 0, ab_command);
  if ((r.data[0] & 0x10U) != toggle_) return sdo_abort(transfer_index_, transfer_sub_, ab_toggle);
  const std::size_t n = std::min<std::size_t>(7, transfer_data_.size() - transfer_at_);
  const bool last = transfer_at_ + n == transfer_data_.size();
  CanFrame answer;
  answer.id = fn_sdo_answer + opt_.node_id;
  answer.len = 8;
  answer.data[0] = static_cast<std::uint8_t>(toggle_ | ((7U - n) << 1) | (last ? 1U : 0U));
  std::copy_n(transfer_data_.begin() + static_cast<long>(transfer_at_), n, answer.data.begin() + 1);
  transfer_at_ += n;
  toggle_ ^= 0x10U;
  if (last) transfer_ = Transfer::idle;
  (void)port_.send(answer);
}

}  // namespace maglead::canopen
