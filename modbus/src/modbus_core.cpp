#include "maglead/modbus/modbus_core.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string_view>

namespace maglead::modbus {

namespace reg = maglead::registers;

/// How a table entry gets its value: from the loop's snapshot (read-only entries), or from the
/// client-writable image (read-write entries). Exactly one binding per table entry.
struct ModbusCore::Binding {
  std::string_view name;
  double (*get)(const Snapshot&);            // read-only entries
  double (*image_get)(const CommandImage&);  // read-write entries
  void (*image_set)(CommandImage&, double);
};

namespace {

using B = ModbusCore;
// From the CMake project version (controller/CMakeLists.txt passes it to this file).
constexpr std::uint16_t kFirmwareVersion = MAGLEAD_VERSION_MAJOR * 256 + MAGLEAD_VERSION_MINOR;

#define SNAP(field) [](const Snapshot& s) { return static_cast<double>(s.field); }
#define TWIN(field) [](const Snapshot& s) { return static_cast<double>(s.twin.field); }
#define CONST(value) [](const Snapshot&) { return static_cast<double>(value); }
#define IMG(field)                                                             \
  nullptr, [](const CommandImage& i) { return static_cast<double>(i.field); }, \
      [](CommandImage& i, double v) { i.field = static_cast<decltype(i.field)>(v); }

// control_owner / control_owner_ipv4 come from the core itself (patched in read_value).
const ModbusCore::Binding kBindings[] = {
    {"device_type", CONST(reg::kDeviceType), nullptr, nullptr},
    {"firmware_version", CONST(kFirmwareVersion), nullptr, nullptr},
    {"register_map_version", CONST(reg::kMapVersion), nullptr, nullptr},
    {"loop_rate_hz", [](const Snapshot&) { return 0.0; }, nullptr, nullptr},  // patched
    {"word_order_probe_u32", CONST(reg::kWordOrderProbeU32), nullptr, nullptr},
    {"word_order_probe_f32", CONST(reg::kWordOrderProbeF32), nullptr, nullptr},
    {"status_word", SNAP(status_word), nullptr, nullptr},
    {"alarm_code", SNAP(alarm_code), nullptr, nullptr},
    {"step_out_count", SNAP(step_out_count), nullptr, nullptr},
    {"drive_state", SNAP(drive_state), nullptr, nullptr},
    {"active_mode", SNAP(active_mode), nullptr, nullptr},
    {"command_status", SNAP(command_status), nullptr, nullptr},
    {"command_reject_reason", SNAP(reject_reason), nullptr, nullptr},
    {"fault_reaction", SNAP(fault_reaction), nullptr, nullptr},
    {"write_refusal_reason", CONST(0), nullptr, nullptr},  // patched
    {"twin_drift_reason", TWIN(drift_reason), nullptr, nullptr},
    {"twin_health_reason", TWIN(health_reason), nullptr, nullptr},
    {"twin_step_out_reason", TWIN(step_out_reason), nullptr, nullptr},
    {"force_loop_state", SNAP(force_loop_state), nullptr, nullptr},
    {"load_force_est_mn", SNAP(observer_force_n), nullptr, nullptr},
    {"load_force_lo_mn", SNAP(observer_force_lo_n), nullptr, nullptr},
    {"load_force_hi_mn", SNAP(observer_force_hi_n), nullptr, nullptr},
    {"force_reached_reason", SNAP(force_reached_reason), nullptr, nullptr},
    {"in_position_reason", SNAP(in_position_reason), nullptr, nullptr},
    {"drive_fault_cause", SNAP(drive_fault_cause), nullptr, nullptr},
    {"drive_error_code", SNAP(drive_error_code), nullptr, nullptr},
    {"observer_basis", SNAP(observer_basis), nullptr, nullptr},
    {"twin_gain_f32", TWIN(gain), nullptr, nullptr},
    {"twin_gain_stderr_f32", TWIN(gain_stderr), nullptr, nullptr},
    {"twin_gain_reference_f32", TWIN(gain_reference), nullptr, nullptr},
    {"twin_drift_observability", TWIN(drift_observability), nullptr, nullptr},
    {"twin_drift_separable", TWIN(drift_separable), nullptr, nullptr},
    {"twin_drift_zero_load_error_n_f32", TWIN(drift_zero_load_n), nullptr, nullptr},
    {"twin_drift_zero_load_stderr_n_f32", TWIN(drift_zero_load_se_n), nullptr, nullptr},
    {"twin_drift_rated_error_n_f32", TWIN(drift_rated_n), nullptr, nullptr},
    {"twin_drift_rated_stderr_n_f32", TWIN(drift_rated_se_n), nullptr, nullptr},
    {"twin_drift_gain_change_f32", TWIN(drift_gain_change), nullptr, nullptr},
    {"twin_drift_friction_change_n_f32", TWIN(drift_friction_change_n), nullptr, nullptr},
    {"twin_drift_known_force_s_f32", TWIN(drift_known_s), nullptr, nullptr},
    {"twin_drift_statistic_f32", TWIN(drift_statistic), nullptr, nullptr},
    {"control_owner", CONST(0), nullptr, nullptr},       // patched
    {"control_owner_ipv4", CONST(0), nullptr, nullptr},  // patched
    {"nut_pos_um", SNAP(nut_pos_m), nullptr, nullptr},
    {"nut_vel_um_s", SNAP(nut_vel_m_s), nullptr, nullptr},
    {"screw_angle_urad", SNAP(screw_angle_rad), nullptr, nullptr},
    {"phase_urad", SNAP(phase_rad), nullptr, nullptr},
    {"force_est_mn", SNAP(force_est_n), nullptr, nullptr},
    {"load_cell_force_mn", SNAP(load_cell_force_n), nullptr, nullptr},
    {"profile_pos_um", SNAP(profile_pos_m), nullptr, nullptr},
    {"active_force_setpoint_mn", SNAP(active_force_setpoint_n), nullptr, nullptr},
    {"active_target_pos_um", SNAP(active_target_pos_m), nullptr, nullptr},
    {"twin_pred_nut_pos_um", TWIN(pred_nut_pos_m), nullptr, nullptr},
    {"twin_pred_force_mn", TWIN(pred_force_n), nullptr, nullptr},
    {"twin_residual_pos_um", TWIN(residual_pos_m), nullptr, nullptr},
    {"twin_residual_force_mn", TWIN(residual_force_n), nullptr, nullptr},
    {"twin_dynamic_force_mn", TWIN(dynamic_force_n), nullptr, nullptr},
    {"loop_cycle_count",
     [](const Snapshot& s) { return static_cast<double>(s.cycle & 0xFFFFFFFFu); }, nullptr,
     nullptr},
    {"loop_overrun_count",
     [](const Snapshot& s) { return static_cast<double>(s.overrun_count & 0xFFFFFFFFu); }, nullptr,
     nullptr},
    {"loop_period_us", SNAP(period_s), nullptr, nullptr},
    {"loop_late_max_us", SNAP(late_max_s), nullptr, nullptr},
    {"nut_pos_m_f32", SNAP(nut_pos_m), nullptr, nullptr},
    {"nut_vel_m_s_f32", SNAP(nut_vel_m_s), nullptr, nullptr},
    {"screw_angle_rad_f32", SNAP(screw_angle_rad), nullptr, nullptr},
    {"phase_rad_f32", SNAP(phase_rad), nullptr, nullptr},
    {"force_est_n_f32", SNAP(force_est_n), nullptr, nullptr},
    {"load_cell_force_n_f32", SNAP(load_cell_force_n), nullptr, nullptr},
    {"profile_pos_m_f32", SNAP(profile_pos_m), nullptr, nullptr},
    {"active_force_setpoint_n_f32", SNAP(active_force_setpoint_n), nullptr, nullptr},
    {"active_target_pos_m_f32", SNAP(active_target_pos_m), nullptr, nullptr},
    {"twin_pred_nut_pos_m_f32", TWIN(pred_nut_pos_m), nullptr, nullptr},
    {"twin_pred_force_n_f32", TWIN(pred_force_n), nullptr, nullptr},
    {"twin_residual_pos_m_f32", TWIN(residual_pos_m), nullptr, nullptr},
    {"twin_residual_force_n_f32", TWIN(residual_force_n), nullptr, nullptr},
    {"twin_dynamic_force_n_f32", TWIN(dynamic_force_n), nullptr, nullptr},
    {"load_force_est_n_f32", SNAP(observer_force_n), nullptr, nullptr},
    {"load_force_lo_n_f32", SNAP(observer_force_lo_n), nullptr, nullptr},
    {"load_force_hi_n_f32", SNAP(observer_force_hi_n), nullptr, nullptr},
    {"force_limit_push_n_f32", CONST(0), nullptr, nullptr},     // patched: configuration
    {"force_limit_pull_n_f32", CONST(0), nullptr, nullptr},     // patched
    {"stroke_min_m_f32", CONST(0), nullptr, nullptr},           // patched
    {"stroke_max_m_f32", CONST(0), nullptr, nullptr},           // patched
    {"force_window_min_m_f32", CONST(0), nullptr, nullptr},     // patched
    {"force_window_max_m_f32", CONST(0), nullptr, nullptr},     // patched
    {"force_speed_limit_m_s_f32", CONST(0), nullptr, nullptr},  // patched
    {"control_word", IMG(control_word)},
    {"mode_command", IMG(mode_command)},
    {"heartbeat", IMG(heartbeat)},
    {"watchdog_ms", IMG(watchdog_s)},
    {"force_setpoint_mn", IMG(force_setpoint_n)},
    {"position_setpoint_um", IMG(position_setpoint_m)},
    {"velocity_limit_um_s", IMG(velocity_limit_m_s)},
    {"accel_limit_um_s2", IMG(accel_limit_m_s2)},
    {"force_setpoint_n_f32", IMG(force_setpoint_n)},
    {"position_setpoint_m_f32", IMG(position_setpoint_m)},
    {"velocity_limit_m_s_f32", IMG(velocity_limit_m_s)},
    {"accel_limit_m_s2_f32", IMG(accel_limit_m_s2)},
    // Coils and discrete inputs are bits of control_word / status_word (handled by address).
    {"enable", nullptr, nullptr, nullptr},
    {"stop", nullptr, nullptr, nullptr},
    {"fault_reset", nullptr, nullptr, nullptr},
    {"resync", nullptr, nullptr, nullptr},
    {"execute", nullptr, nullptr, nullptr},
    {"ready", nullptr, nullptr, nullptr},
    {"enabled", nullptr, nullptr, nullptr},
    {"fault", nullptr, nullptr, nullptr},
    {"moving", nullptr, nullptr, nullptr},
    {"in_position", nullptr, nullptr, nullptr},
    {"force_reached", nullptr, nullptr, nullptr},
    {"step_out", nullptr, nullptr, nullptr},
    {"drift_warning", nullptr, nullptr, nullptr},
    {"watchdog_expired", nullptr, nullptr, nullptr},
    {"twin_healthy", nullptr, nullptr, nullptr},
    {"step_out_warning", nullptr, nullptr, nullptr},
    {"stopped", nullptr, nullptr, nullptr},
    {"owned", nullptr, nullptr, nullptr},
    {"stroke_limit", nullptr, nullptr, nullptr},
    {"twin_lagging", nullptr, nullptr, nullptr},
    {"force_limited", nullptr, nullptr, nullptr},
};
#undef SNAP
#undef TWIN
#undef CONST
#undef IMG

std::uint16_t be16(const std::uint8_t* p) { return static_cast<std::uint16_t>((p[0] << 8) | p[1]); }
void put16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v >> 8);
  p[1] = static_cast<std::uint8_t>(v & 0xFF);
}

// Coil k is bit k of the control word (the coil addresses are the bit numbers).
void set_coil(std::uint16_t& control_word, std::uint32_t addr, bool on) {
  const auto mask = static_cast<std::uint16_t>(1u << addr);
  control_word = static_cast<std::uint16_t>(on ? (control_word | mask) : (control_word & ~mask));
}

// A read reply: function code, byte count, then the n data bytes already in out + 2.
std::size_t byte_count_reply(std::uint8_t fc, std::size_t n, std::uint8_t* out) {
  out[0] = fc;
  out[1] = static_cast<std::uint8_t>(n);
  return 2 + n;
}

/// A register one write request has set, and the value it left in the image.
struct Written {
  const reg::Register* reg;
  const ModbusCore::Binding* binding;
  double value;
};

/// False when register r, just set to v, overwrote the other copy of the same setpoint (the
/// scaled integer and its float32 twin share one image field) that this request set earlier to
/// a value more than half the integer copy's unit away: a block written back with one copy
/// changed, where the later one would win unnoticed. An agreeing copy takes the field over.
bool copies_agree(const reg::Register& r, double v, const CommandImage& image,
                  std::span<Written> earlier) {
  for (auto& w : earlier) {
    const double now = w.binding->image_get(image);
    if (now == w.value) continue;  // another field
    const double unit_si = r.type == reg::Type::f32 ? w.reg->scale : r.scale;
    const double slack = 0.5 * unit_si + std::numeric_limits<float>::epsilon() * std::abs(v);
    if (std::abs(v - w.value) > slack) return false;
    w.value = now;
  }
  return true;
}

struct DeviceObject {
  std::uint8_t id;
  std::string_view value;
};

}  // namespace

ModbusCore::ModbusCore(Controller& controller, ServerOptions options)
    : controller_(controller),
      options_(std::move(options)),
      reg_slots_(65536),
      coil_slots_(65536),
      di_slots_(65536),
      image_(controller.initial_image()) {
  const auto table = reg::table();
  bindings_.assign(table.size(), nullptr);
  configured_.resize(table.size());
  for (std::size_t i = 0; i < table.size(); ++i) {
    const auto& r = table[i];
    for (const auto& b : kBindings)
      if (b.name == r.name) bindings_[i] = &b;
    if (!bindings_[i])
      throw std::logic_error("register '" + std::string(r.name) + "' has no server binding");
    configured_[i] = configured_value(r.name);  // the configuration is fixed: looked up once
    const bool rw = r.access == reg::Access::read_write;
    if (r.table == reg::Table::holding_register || r.table == reg::Table::input_register) {
      if (rw ? !(bindings_[i]->image_get && bindings_[i]->image_set) : !bindings_[i]->get)
        throw std::logic_error("register '" + std::string(r.name) +
                               "' is bound to the wrong source");
    }
    auto& slots = r.table == reg::Table::coil             ? coil_slots_
                  : r.table == reg::Table::discrete_input ? di_slots_
                                                          : reg_slots_;
    for (int w = 0; w < reg::word_count(r.type); ++w) {
      auto& slot = slots.at(r.address + static_cast<std::size_t>(w));
      if (slot.reg >= 0)
        throw std::logic_error("register '" + std::string(r.name) + "' overlaps another");
      slot = {static_cast<std::int16_t>(i), static_cast<std::int8_t>(w)};
    }
  }
  if (std::size(kBindings) != table.size())
    throw std::logic_error("server bindings name registers not in the table");
  // Reserved addresses inside the documented blocks read as 0 (writes to them stay refused).
  for (const auto& range : reg::mapped_ranges()) {
    if (range.table != reg::Table::input_register && range.table != reg::Table::holding_register)
      continue;
    for (std::uint32_t a = range.first; a < range.first + range.count; ++a) {
      auto& slot = reg_slots_.at(a);
      if (slot.reg < 0)
        slot.reg = range.table == reg::Table::input_register ? kReservedInput : kReservedHolding;
    }
  }
  for (const auto& r : table)
    if (!reg::in_mapped_range(r.table, r.address))
      throw std::logic_error("register '" + std::string(r.name) +
                             "' lies outside the mapped ranges");
  check_limits_fit_the_map();
}

/// A configured stroke or safe force the setpoint registers cannot carry would be published in
/// the limits block (IR 140-147) and then refused as out of range: refused at start instead.
void ModbusCore::check_limits_fit_the_map() const {
  const auto& a = controller_.config().actuator;
  const auto* pos = reg::find("position_setpoint_um");
  const auto* force = reg::find("force_setpoint_mn");
  char b[320];
  if (a.stroke_min_m < pos->min - 1e-12 || a.stroke_max_m > pos->max + 1e-12) {
    std::snprintf(b, sizeof b,
                  "the stroke %g .. %g m lies beyond what position_setpoint carries (%g .. %g m): "
                  "set stroke_min_m and stroke_max_m in actuator.toml inside it",
                  a.stroke_min_m, a.stroke_max_m, pos->min, pos->max);
    throw std::invalid_argument(b);
  }
  const double push = controller_.safe_force_limit_n(1.0),
               pull = controller_.safe_force_limit_n(-1.0);
  if (pull < force->min || push > force->max) {
    std::snprintf(b, sizeof b,
                  "the safe force limits %.2f / %.2f N lie beyond what force_setpoint carries "
                  "(%g .. %g N): lower safe_force_fraction in actuator.toml",
                  push, pull, force->min, force->max);
    throw std::invalid_argument(b);
  }
}

std::uint16_t ModbusCore::owner() const {
  std::lock_guard lock(mutex_);
  return owner_;
}

void ModbusCore::client_closed(std::uint16_t client_id) {
  std::lock_guard lock(mutex_);
  if (owner_ == 0 || owner_ != client_id) return;
  owner_ = 0, owner_ipv4_ = 0;
  // Owner loss is a fault: the loop runs its reaction at once. Nobody holds the control word's
  // levels any more, so it starts clear: the next owner claims with a fresh enable edge.
  image_.control_word = 0;
  if (!controller_.post(Command{image_, false, true})) controller_.signal_owner_lost();
}

void ModbusCore::count_comm_error() {
  std::lock_guard lock(mutex_);
  ++comm_errors_;
}

bool ModbusCore::refuse(registers::Refusal why, Exception& ex) {
  refusal_ = static_cast<std::uint16_t>(why);
  ex = Exception::server_device_failure;
  return false;
}

bool ModbusCore::refuse_value(registers::Refusal why, Exception& ex) {
  refusal_ = static_cast<std::uint16_t>(why);
  ex = Exception::illegal_data_value;
  return false;
}

std::size_t ModbusCore::exception(std::uint8_t function, Exception code, std::uint8_t* out) {
  out[0] = static_cast<std::uint8_t>(function | 0x80);
  out[1] = static_cast<std::uint8_t>(code);
  return 2;
}

std::optional<double> ModbusCore::configured_value(std::string_view name) const {
  const auto& c = controller_.config();
  const auto& a = c.actuator;
  if (name == "loop_rate_hz") return a.sample_rate_hz;
  if (name == "force_limit_push_n_f32") return controller_.safe_force_limit_n(1.0);
  if (name == "force_limit_pull_n_f32") return controller_.safe_force_limit_n(-1.0);
  if (name == "stroke_min_m_f32") return a.stroke_min_m;
  if (name == "stroke_max_m_f32") return a.stroke_max_m;
  if (name == "force_window_min_m_f32") return controller_.force_window().lo_m;
  if (name == "force_window_max_m_f32") return controller_.force_window().hi_m;
  if (name == "force_speed_limit_m_s_f32") return c.force_speed_limit_m_s;
  return std::nullopt;
}

double ModbusCore::read_value(std::size_t i, const Snapshot& snap) const {
  const auto& r = reg::table()[i];
  const Binding& b = *bindings_[i];
  if (r.access == reg::Access::read_write) return b.image_get(image_);
  if (r.name == "control_owner") return owner_;
  if (r.name == "control_owner_ipv4") return owner_ipv4_;
  if (r.name == "write_refusal_reason") return refusal_;
  if (configured_[i]) return *configured_[i];
  if (r.name == "status_word") return snap.status_word | (owner_ ? 1u << reg::kOwned : 0u);
  return b.get(snap);
}

std::size_t ModbusCore::read_registers(bool input_only, std::uint16_t start, std::uint16_t count,
                                       std::uint8_t* out, std::size_t& n, Exception& ex) {
  if (count < 1 || count > 125) return ex = Exception::illegal_data_value, 0;
  if (start + count > 65536) return ex = Exception::illegal_data_address, 0;
  const Snapshot snap = controller_.snapshot();  // one cycle for the whole reply: never torn
  const auto table = reg::table();
  std::uint32_t addr = start;
  const std::uint32_t end = start + count;
  std::uint8_t* p = out;
  while (addr < end) {
    const Slot s = reg_slots_[addr];
    if (s.reg == kReservedInput || (s.reg == kReservedHolding && !input_only)) {
      put16(p, 0);  // reserved inside a documented block
      p += 2;
      ++addr;
      continue;
    }
    if (s.reg < 0 || s.word != 0) return ex = Exception::illegal_data_address, 0;
    const auto& r = table[static_cast<std::size_t>(s.reg)];
    if (input_only && r.table != reg::Table::input_register)
      return ex = Exception::illegal_data_address, 0;
    const int w = reg::word_count(r.type);
    if (addr + static_cast<std::uint32_t>(w) > end) return ex = Exception::illegal_data_address, 0;
    std::uint16_t words[2];
    reg::encode(r, read_value(static_cast<std::size_t>(s.reg), snap), words);
    for (int k = 0; k < w; ++k, p += 2) put16(p, words[k]);
    addr += static_cast<std::uint32_t>(w);
  }
  n = static_cast<std::size_t>(p - out);
  return n;
}

bool ModbusCore::decode_registers(std::uint16_t start, std::uint16_t count,
                                  const std::uint8_t* data, CommandImage& image, bool& heartbeat,
                                  bool& touches_control, Exception& ex) {
  const auto table = reg::table();
  std::uint32_t addr = start;
  const std::uint32_t end = static_cast<std::uint32_t>(start) + count;
  if (end > 65536) return ex = Exception::illegal_data_address, false;
  std::array<Written, 16> written{};  // more than the holding registers one request can write
  std::size_t n_written = 0;
  while (addr < end) {
    const Slot s = reg_slots_[addr];
    if (s.reg < 0 || s.word != 0) return ex = Exception::illegal_data_address, false;
    const auto& r = table[static_cast<std::size_t>(s.reg)];
    if (r.table != reg::Table::holding_register || r.access != reg::Access::read_write)
      return ex = Exception::illegal_data_address, false;
    const int w = reg::word_count(r.type);
    if (addr + static_cast<std::uint32_t>(w) > end)
      return ex = Exception::illegal_data_address, false;
    std::uint16_t words[2] = {0, 0};
    const std::uint8_t* d = data + std::size_t{2} * (addr - start);
    for (std::size_t k = 0; k < static_cast<std::size_t>(w); ++k) words[k] = be16(d + 2 * k);
    const double decoded = reg::decode(r, words);
    // A round float32 sent low word first (10.0 as 0, 16672) decodes to a subnormal, inside every
    // setpoint's range and never a real setpoint: staged, it would be held as 0.
    if (r.type == reg::Type::f32 && decoded != 0.0 &&
        std::abs(decoded) < std::numeric_limits<float>::min())
      return refuse_value(reg::Refusal::word_order, ex);
    if (!reg::in_range(r, decoded)) return refuse_value(reg::Refusal::out_of_range, ex);
    // A float32 taken within its rounding slack past a limit is the limit: its integer mirror
    // then reads inside the documented range, and the block written back as read is taken.
    const double v = std::clamp(decoded, r.min, r.max);
    const auto* binding = bindings_[static_cast<std::size_t>(s.reg)];
    binding->image_set(image, v);
    if (!copies_agree(r, v, image, std::span(written.data(), n_written)))
      return refuse_value(reg::Refusal::copies_disagree, ex);
    if (n_written < written.size()) written[n_written++] = {&r, binding, binding->image_get(image)};
    if (r.name == "heartbeat") heartbeat = true;
    if (r.name == "control_word") touches_control = true;
    if (r.name == "position_setpoint_um" || r.name == "position_setpoint_m_f32")
      request_writes_target_ = true;  // taken once the whole request is accepted (handle)
    addr += static_cast<std::uint32_t>(w);
  }
  return true;
}

bool ModbusCore::write_image(const ClientInfo& client, CommandImage next, bool heartbeat,
                             bool touches_control, Exception& ex) {
  using namespace registers;
  const auto cw = next.control_word;
  const auto has = [&](int b) { return (cw >> b) & 1u; };
  if (cw & ~kControlWordMask) return refuse_value(Refusal::bad_control_word, ex);
  // One edge command per write, and no command while the stop bit is held.
  if (has(kExecute) && (has(kStop) || has(kFaultReset) || has(kResync)))
    return refuse_value(Refusal::bad_control_word, ex);
  const auto& a = controller_.config().actuator;
  // Within half an integer register's resolution (0.5 mN, 0.5 µm) a limit is the limit: its
  // float32 copy (IR 140-147) or a staged setpoint's integer mirror written back lands there,
  // rounded by that much either way; it is taken as the limit itself.
  constexpr double kForceSlack_n = 0.5e-3, kPositionSlack_m = 0.5e-6;
  const double f = next.force_setpoint_n, f_limit = controller_.safe_force_limit_n(f);
  if (std::abs(f) > std::abs(f_limit) + kForceSlack_n)
    return refuse_value(Refusal::force_beyond_safe_limit, ex);
  if (std::abs(f) > std::abs(f_limit)) next.force_setpoint_n = f_limit;
  if (next.position_setpoint_m < a.stroke_min_m - kPositionSlack_m ||
      next.position_setpoint_m > a.stroke_max_m + kPositionSlack_m)
    return refuse_value(Refusal::position_outside_stroke, ex);
  next.position_setpoint_m = std::clamp(next.position_setpoint_m, a.stroke_min_m, a.stroke_max_m);

  // Broadcast (RTU unit 0) may stage setpoints and feed the heartbeat, never change the drive's
  // state: one frame would enable, switch or reset every drive on the line at once.
  if (client.broadcast &&
      (next.control_word != image_.control_word || next.mode_command != image_.mode_command))
    return refuse(registers::Refusal::broadcast_state_change, ex);

  const bool changed = next != image_;
  if (changed || heartbeat) {
    if (!controller_.post(Command{next, heartbeat})) return ex = Exception::server_busy, false;
  }
  const bool old_enable = (image_.control_word >> kEnable) & 1u;
  const bool new_enable = has(kEnable);
  // Control is claimed only by a rising edge of enable while nobody owns it: never by writing
  // first.
  if (touches_control && !old_enable && new_enable && owner_ == 0 && client.id != 0)
    owner_ = client.id, owner_ipv4_ = client.ipv4;
  if (old_enable && !new_enable && owner_ == client.id) owner_ = 0, owner_ipv4_ = 0;
  image_ = next;
  return true;
}

// Until a client writes a target, the staged one is where the nut is at each request: an execute
// in position mode without a written target holds the nut where it is, as a drive takes its
// actual position at enable, instead of moving it to mid-stroke.
void ModbusCore::stage_position_until_written() {
  if (target_written_) return;
  const Snapshot snap = controller_.snapshot();
  if (!snap.actuator_read) return;  // nut_pos_m is no measurement yet
  const auto& a = controller_.config().actuator;
  image_.position_setpoint_m = std::clamp(snap.nut_pos_m, a.stroke_min_m, a.stroke_max_m);
}

std::size_t ModbusCore::handle(const ClientInfo& client, const std::uint8_t* pdu, std::size_t len,
                               std::uint8_t* out) {
  std::lock_guard lock(mutex_);
  stage_position_until_written();
  ++bus_messages_;
  ++server_messages_;
  request_writes_target_ = false;
  const std::size_t n = dispatch(client, pdu, len, out);
  if (n >= 2 && !(out[0] & 0x80) && request_writes_target_) target_written_ = true;
  if (n >= 2 && (out[0] & 0x80)) {
    ++exceptions_;
    if (out[1] == static_cast<std::uint8_t>(Exception::server_busy)) ++busy_;
  }
  if (client.broadcast) {
    ++no_response_;
    return 0;
  }
  return n;
}

std::size_t ModbusCore::dispatch(const ClientInfo& client, const std::uint8_t* pdu, std::size_t len,
                                 std::uint8_t* out) {
  if (len < 1) return 0;
  const std::uint8_t fc = pdu[0];
  // Writes are gated here, before any parsing, so every write function refuses the same way.
  const bool is_write = fc == 5 || fc == 6 || fc == 15 || fc == 16 || fc == 23;
  if (is_write) {
    if (options_.read_only) return exception(fc, Exception::illegal_function, out);
    // Not busy: retrying cannot help until the owner lets go. 04 is not retried by clients; the
    // reason is in write_refusal_reason.
    if (owner_ != 0 && owner_ != client.id) {
      Exception ex = Exception::illegal_function;
      refuse(registers::Refusal::not_owner, ex);
      return exception(fc, ex, out);
    }
  }
  switch (fc) {
    case 1:
    case 2:
      return handle_read_bits(pdu, len, out);
    case 3:
    case 4:
      return handle_read_registers(pdu, len, out);
    case 5:
      return handle_write_coil(client, pdu, len, out);
    case 15:
      return handle_write_coils(client, pdu, len, out);
    case 6:
      return handle_write_register(client, pdu, len, out);
    case 16:
      return handle_write_registers(client, pdu, len, out);
    case 23:
      return handle_read_write_registers(client, pdu, len, out);
    case 8:
      return handle_diagnostics(pdu, len, out);
    case 43:
      return handle_device_identification(pdu, len, out);
    default:
      return exception(fc, Exception::illegal_function, out);
  }
}

// FC1 read coils (bits of the client's control word) / FC2 read discrete inputs (bits of the
// status word, plus the owned bit the core adds).
std::size_t ModbusCore::handle_read_bits(const std::uint8_t* pdu, std::size_t len,
                                         std::uint8_t* out) {
  const std::uint8_t fc = pdu[0];
  if (len != 5) return exception(fc, Exception::illegal_data_value, out);
  const std::uint16_t start = be16(pdu + 1), count = be16(pdu + 3);
  if (count < 1 || count > 2000) return exception(fc, Exception::illegal_data_value, out);
  if (start + count > 65536) return exception(fc, Exception::illegal_data_address, out);
  const auto& slots = fc == 1 ? coil_slots_ : di_slots_;
  std::uint16_t word = image_.control_word;
  if (fc == 2) {
    const Snapshot snap = controller_.snapshot();
    word = static_cast<std::uint16_t>(snap.status_word | (owner_ ? 1u << reg::kOwned : 0u));
  }
  const auto bytes = static_cast<std::size_t>((count + 7) / 8);
  out[0] = fc;
  out[1] = static_cast<std::uint8_t>(bytes);
  std::memset(out + 2, 0, bytes);
  for (std::uint32_t k = 0; k < count; ++k) {
    const Slot s = slots[start + k];
    if (s.reg < 0) return exception(fc, Exception::illegal_data_address, out);
    const auto bit = reg::table()[static_cast<std::size_t>(s.reg)].address;
    if ((word >> bit) & 1u)
      out[2 + k / 8] = static_cast<std::uint8_t>(out[2 + k / 8] | (1u << (k % 8)));
  }
  return 2 + bytes;
}

// FC3 read holding registers / FC4 read input registers.
std::size_t ModbusCore::handle_read_registers(const std::uint8_t* pdu, std::size_t len,
                                              std::uint8_t* out) {
  const std::uint8_t fc = pdu[0];
  if (len != 5) return exception(fc, Exception::illegal_data_value, out);
  Exception ex = Exception::illegal_function;
  std::size_t n = 0;
  if (!read_registers(fc == 4, be16(pdu + 1), be16(pdu + 3), out + 2, n, ex))
    return exception(fc, ex, out);
  return byte_count_reply(fc, n, out);
}

// FC5 write single coil: one bit of the control word; FF00 sets it, 0000 clears it.
std::size_t ModbusCore::handle_write_coil(const ClientInfo& client, const std::uint8_t* pdu,
                                          std::size_t len, std::uint8_t* out) {
  const std::uint8_t fc = pdu[0];
  if (len != 5) return exception(fc, Exception::illegal_data_value, out);
  const std::uint16_t addr = be16(pdu + 1), value = be16(pdu + 3);
  if (coil_slots_[addr].reg < 0) return exception(fc, Exception::illegal_data_address, out);
  if (value != 0xFF00 && value != 0x0000) return exception(fc, Exception::illegal_data_value, out);
  CommandImage next = image_;
  set_coil(next.control_word, addr, value != 0);
  return apply_and_echo(client, next, false, true, pdu, out);
}

// FC15 write multiple coils: bits of the control word, all applied as one image change.
std::size_t ModbusCore::handle_write_coils(const ClientInfo& client, const std::uint8_t* pdu,
                                           std::size_t len, std::uint8_t* out) {
  const std::uint8_t fc = pdu[0];
  if (len < 7) return exception(fc, Exception::illegal_data_value, out);
  const std::uint16_t start = be16(pdu + 1), count = be16(pdu + 3);
  const std::uint8_t bytes = pdu[5];
  if (count < 1 || count > 1968 || bytes != (count + 7) / 8 || len != 6u + bytes)
    return exception(fc, Exception::illegal_data_value, out);
  if (start + count > 65536) return exception(fc, Exception::illegal_data_address, out);
  CommandImage next = image_;
  for (std::uint32_t k = 0; k < count; ++k) {
    const std::uint32_t addr = start + k;
    if (coil_slots_[addr].reg < 0) return exception(fc, Exception::illegal_data_address, out);
    const bool on = (pdu[6 + k / 8] >> (k % 8)) & 1u;
    set_coil(next.control_word, addr, on);
  }
  return apply_and_echo(client, next, false, true, pdu, out);
}

// FC6 write single register.
std::size_t ModbusCore::handle_write_register(const ClientInfo& client, const std::uint8_t* pdu,
                                              std::size_t len, std::uint8_t* out) {
  if (len != 5) return exception(pdu[0], Exception::illegal_data_value, out);
  return write_registers_and_echo(client, be16(pdu + 1), 1, pdu + 3, pdu, out);
}

// FC16 write multiple registers.
std::size_t ModbusCore::handle_write_registers(const ClientInfo& client, const std::uint8_t* pdu,
                                               std::size_t len, std::uint8_t* out) {
  if (len < 6) return exception(pdu[0], Exception::illegal_data_value, out);
  const std::uint16_t start = be16(pdu + 1), count = be16(pdu + 3);
  if (count < 1 || count > 123 || pdu[5] != 2 * count || len != 6u + 2u * count)
    return exception(pdu[0], Exception::illegal_data_value, out);
  return write_registers_and_echo(client, start, count, pdu + 6, pdu, out);
}

// FC23 read/write multiple registers: write first, then read (the spec's order). The read range
// is checked before anything is written, so a bad read address leaves the image as it was.
std::size_t ModbusCore::handle_read_write_registers(const ClientInfo& client,
                                                    const std::uint8_t* pdu, std::size_t len,
                                                    std::uint8_t* out) {
  const std::uint8_t fc = pdu[0];
  if (len < 10) return exception(fc, Exception::illegal_data_value, out);
  const std::uint16_t rstart = be16(pdu + 1), rcount = be16(pdu + 3);
  const std::uint16_t wstart = be16(pdu + 5), wcount = be16(pdu + 7);
  if (rcount < 1 || rcount > 125 || wcount < 1 || wcount > 121 || pdu[9] != 2 * wcount ||
      len != 10u + 2u * wcount)
    return exception(fc, Exception::illegal_data_value, out);
  Exception ex = Exception::illegal_function;
  std::size_t n = 0;
  if (!read_registers(false, rstart, rcount, out + 2, n, ex)) return exception(fc, ex, out);
  CommandImage next = image_;
  bool heartbeat = false, touches = false;
  if (!decode_registers(wstart, wcount, pdu + 10, next, heartbeat, touches, ex))
    return exception(fc, ex, out);
  if (!write_image(client, next, heartbeat, touches, ex)) return exception(fc, ex, out);
  if (!read_registers(false, rstart, rcount, out + 2, n, ex)) return exception(fc, ex, out);
  return byte_count_reply(fc, n, out);
}

// FC6 and FC16 once their framing is checked: decode the words into a copy of the image, so a
// bad word changes nothing, then apply it.
std::size_t ModbusCore::write_registers_and_echo(const ClientInfo& client, std::uint16_t start,
                                                 std::uint16_t count, const std::uint8_t* data,
                                                 const std::uint8_t* pdu, std::uint8_t* out) {
  CommandImage next = image_;
  bool heartbeat = false, touches = false;
  Exception ex = Exception::illegal_function;
  if (!decode_registers(start, count, data, next, heartbeat, touches, ex))
    return exception(pdu[0], ex, out);
  return apply_and_echo(client, next, heartbeat, touches, pdu, out);
}

// FC5/6/15/16 answer a successful write with the request's first five bytes (function, address,
// value or count).
std::size_t ModbusCore::apply_and_echo(const ClientInfo& client, const CommandImage& next,
                                       bool heartbeat, bool touches_control,
                                       const std::uint8_t* pdu, std::uint8_t* out) {
  Exception ex = Exception::illegal_function;
  if (!write_image(client, next, heartbeat, touches_control, ex)) return exception(pdu[0], ex, out);
  std::memcpy(out, pdu, 5);
  return 5;
}

// FC8 diagnostics: sub-function 0000 echoes the request whatever its length; the others carry one
// data word and answer with it replaced by a counter.
std::size_t ModbusCore::handle_diagnostics(const std::uint8_t* pdu, std::size_t len,
                                           std::uint8_t* out) {
  if (len < 3) return exception(pdu[0], Exception::illegal_data_value, out);
  const std::uint16_t sub = be16(pdu + 1);
  if (sub == 0x0000) {
    std::memcpy(out, pdu, len);
    return len;
  }
  if (len != 5) return exception(pdu[0], Exception::illegal_data_value, out);
  std::uint16_t value = 0;
  if (!diagnostic_value(sub, be16(pdu + 3), value))
    return exception(pdu[0], Exception::illegal_function, out);
  std::memcpy(out, pdu, 3);
  put16(out + 3, value);
  return 5;
}

// The data word FC8 answers sub-function sub with (data: the request's); false if unsupported.
bool ModbusCore::diagnostic_value(std::uint16_t sub, std::uint16_t data, std::uint16_t& value) {
  switch (sub) {
    case 0x01:  // restart communications: clear counters, echo
    case 0x0A:
      bus_messages_ = comm_errors_ = exceptions_ = server_messages_ = no_response_ = busy_ = 0;
      value = data;
      return true;
    case 0x0B:
      return value = bus_messages_, true;
    case 0x0C:
      return value = comm_errors_, true;
    case 0x0D:
      return value = exceptions_, true;
    case 0x0E:
      return value = server_messages_, true;
    case 0x0F:
      return value = no_response_, true;
    case 0x10:  // NAKs: never sent
      return value = 0, true;
    case 0x11:
      return value = busy_, true;
    case 0x12:  // character overruns: the OS would lose them, not us
      return value = 0, true;
    default:
      return false;
  }
}

// FC43 encapsulated interface, MEI 14 read device identification: picks the objects to send.
std::size_t ModbusCore::handle_device_identification(const std::uint8_t* pdu, std::size_t len,
                                                     std::uint8_t* out) {
  const std::uint8_t fc = pdu[0];
  // A wrong MEI type is an unknown function whatever the length; only MEI 14 has a length rule.
  if (len != 4)
    return exception(
        fc,
        len >= 2 && pdu[1] != 0x0E ? Exception::illegal_function : Exception::illegal_data_value,
        out);
  if (pdu[1] != 0x0E) return exception(fc, Exception::illegal_function, out);
  const std::uint8_t code = pdu[2];
  const std::uint8_t object = pdu[3];
  if (code < 1 || code > 4) return exception(fc, Exception::illegal_data_value, out);
  std::size_t first = 0, last = 0;  // inclusive object range to send
  if (code == 4) {
    if (object > 5) return exception(fc, Exception::illegal_data_address, out);
    first = last = object;
  } else {
    last = code == 1 ? 2 : 5;
    first = object <= last ? object : 0;  // unknown start: restart at object 0
  }
  return device_identification_reply(code, first, last, out);
}

// The FC43/14 reply with objects first..last (inclusive). Values are cut at 64 bytes, so every
// range fits in one response and "more follows" is always 0.
std::size_t ModbusCore::device_identification_reply(std::uint8_t code, std::size_t first,
                                                    std::size_t last, std::uint8_t* out) const {
  const std::array<DeviceObject, 6> objects{{{0, "maglead project"},
                                             {1, "MAGLEAD-CTRL"},
                                             {2, MAGLEAD_VERSION},
                                             {3, MAGLEAD_VENDOR_URL},
                                             {4, "maglead magnetic lead-screw actuator controller"},
                                             {5, options_.model_name}}};
  out[0] = 43;
  out[1] = 0x0E;
  out[2] = code;
  out[3] = 0x82;  // conformity: regular identification, stream and individual access
  out[4] = 0;     // more follows: everything fits in one response
  out[5] = 0;
  std::size_t p = 7, count = 0;
  for (std::size_t i = first; i <= last; ++i) {
    const auto v = objects[i].value.substr(0, 64);
    out[p++] = objects[i].id;
    out[p++] = static_cast<std::uint8_t>(v.size());
    std::memcpy(out + p, v.data(), v.size());
    p += v.size();
    ++count;
  }
  out[6] = static_cast<std::uint8_t>(count);
  return p;
}

}  // namespace maglead::modbus
