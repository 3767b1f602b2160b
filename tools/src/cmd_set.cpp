// maglead set / enable / disable / reset: command a controller over Modbus the way a PLC does
// (staged setpoint, mode_command, execute edge, ack/done handshake). Every value is checked as
// the server checks it, before anything is sent.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <functional>
#include <limits>
#include <optional>
#include <span>
#include <string>

#include "operator_cli.hpp"

namespace maglead::cli {
namespace {

namespace reg = maglead::registers;
using op::ClientError;
using Kind = ClientError::Kind;

struct CommandFlags {
  std::string config = default_config_dir(), calibration, wait = "30s", hold;
  bool no_wait = false, no_claim = false;
  op::CommandOptions options() const {
    op::CommandOptions c;
    c.wait_done = !no_wait;
    c.claim = !no_claim;
    c.done_timeout_s = parse_duration_s(wait, "--wait");
    return c;
  }
};

void add_command_flags(CLI::App* cmd, const std::shared_ptr<CommandFlags>& f, bool limits) {
  if (limits) {
    add_config_option(cmd, f->config,
                      "stroke, safe force fraction; read only when the controller does not "
                      "report its own limits (register map version 1)");
    cmd->add_option("--calibration", f->calibration,
                    "Force calibration the controller uses, read only as --config is (default: "
                    "CONFIG/calibration.toml)");
  }
  cmd->add_flag("--no-wait", f->no_wait, "Return once the controller acknowledged, not when done");
  cmd->add_option("--wait", f->wait, "How long to wait for done (e.g. 30s)")->capture_default_str();
}

constexpr const char* kHoldHelp =
    "Keep control this long (e.g. 10s), then release it. Default: until Ctrl-C (a reference "
    "move: released once it is done). Release brings "
    "a force to 0 N first, then clears enable: the drive is disabled without a fault (a "
    "position is no longer controlled, the screw stays where it is)";

volatile std::sig_atomic_t g_interrupted = 0;
void on_interrupt(int signal_number) { g_interrupted = signal_number; }
void catch_interrupt() {
  g_interrupted = 0;
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
}

// How long a release waits for the force loop to bring the load to 0 N before clearing enable.
constexpr double kReleaseToZero_s = 5.0;

/// Releases control cleanly. In force mode the force is first brought to 0 N by the loop, so the
/// load is not left pressed and the next command starts from a known load; then enable is
/// cleared (drive disabled, no owner-loss fault). Returns what was done, in words; a reason the
/// caller has said already (`said`, the failed command's) is not said twice.
std::string release(op::Client& client, bool force_mode, const std::string& said = {}) {
  std::string done;
  if (force_mode) {
    op::CommandOptions to_zero;
    to_zero.claim = false;  // this client owns control already
    to_zero.done_timeout_s = kReleaseToZero_s;
    try {
      op::execute(client, reg::Mode::force, {{"force_setpoint_mn", 0.0}}, to_zero);
      done = "force brought to 0 N, ";
    } catch (const ClientError& e) {
      // The controller's own answer (the stroke end, a fault, the timeout), never a guess.
      std::string why = e.what();
      if (why == said) why = "the same reason";
      if (why.starts_with("execute: ")) why.erase(0, 9);
      done = "force not brought to 0 N: " + why + "; ";
    }
  }
  op::disable(client, {});
  return done + "enable cleared, drive disabled without a fault";
}

/// `v` with `places` decimals, as the lines below say seconds.
std::string fixed(double v, int places) {
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", places, v);
  return b;
}

/// The controller lost while holding: what that means for the drive and what to type, with the
/// line's own error after it. `again` is the command that held ("maglead enable").
[[noreturn]] void lost_while_holding(const ClientError& e, const std::string& held, bool force_mode,
                                     const std::string& again) {
  throw ClientError(
      e.kind(),
      "lost the controller while holding " + held +
          ": control and the hold are lost; a controller still running faults with owner_lost "
          "and runs its fault reaction (by default " +
          (force_mode ? "the force ramped to 0 N" : "the position held") +
          "; docs/plc.md, 'Fault reactions'). Check that 'maglead serve' runs (start it again if "
          "it stopped), then run '" +
          again + "' again (" + e.what() + ")");
}

/// Keeps control until Ctrl-C or SIGTERM (or for `hold`), then releases it cleanly (release).
/// Says both, so nothing happens in secret.
void hold_then_release(op::Client& client, const std::string& hold, const op::CommandOptions& o,
                       const std::string& held, bool force_mode, const std::string& again) {
  const double hold_s =
      hold.empty() ? std::numeric_limits<double>::infinity() : parse_duration_s(hold, "--hold");
  const std::string released = force_mode ? " (force to 0 N, drive disabled)" : " (drive disabled)";
  if (hold.empty())
    print_line("holding " + held + ": control kept until Ctrl-C, then released" + released);
  else
    print_line("holding " + held + " for " + fixed(hold_s, 1) + " s, then released" + released);
  std::fflush(stdout);
  const auto t0 = std::chrono::steady_clock::now();
  try {
    op::hold(client, hold_s, o, [] { return g_interrupted != 0; });
  } catch (const ClientError& e) {
    if (g_interrupted) fresh_line_after_interrupt(g_interrupted);
    if (e.kind() == Kind::connection || e.kind() == Kind::no_reply)
      lost_while_holding(e, held, force_mode, again);
    throw;
  }
  if (g_interrupted) fresh_line_after_interrupt(g_interrupted);
  const double held_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::string done = release(client, force_mode);
  print_line("held for " + fixed(held_s, 1) + " s; released: " + done +
             (force_mode ? "" : " (the screw stays where it is)"));
}

/// drive_state (IR 13).
double drive_state(op::Client& client) {
  const auto* r = reg::find("drive_state");
  return client.read_range(reg::Table::input_register, r->address, 1).at("drive_state");
}

/// The latched alarm when the drive is in fault (IR 11-13), else nothing.
std::optional<double> fault_alarm(op::Client& client) {
  const auto* r = reg::find("alarm_code");
  const auto v = client.read_range(reg::Table::input_register, r->address, 3);
  if (v.at("drive_state") != static_cast<double>(reg::DriveState::fault)) return std::nullopt;
  return v.at("alarm_code");
}

/// --no-claim writes into control held by the line's one master, over RTU (an `enable` running in
/// another terminal on the same serial line). Over TCP each connection owns control for itself and
/// the controller refuses another's writes (04 not_owner); on a drive nobody enabled the execute
/// would be rejected (not_enabled), the setpoint and mode left staged for anyone's next execute.
/// Each refused before anything is written.
void refuse_no_claim_unless_enabled(op::Client& client) {
  if (client.endpoint().serial.empty())
    throw ClientError(Kind::refused_locally,
                      "refused, nothing sent: --no-claim writes into control another process on "
                      "the same serial line (Modbus RTU) holds; over TCP each connection owns "
                      "control for itself and the controller refuses another's writes "
                      "(not_owner): drop --no-claim (set claims control itself)");
  if (const auto who = op::other_owner(client))
    throw ClientError(Kind::refused_locally,
                      "refused, nothing sent: " + *who +
                          " owns control and the controller refuses others' writes (not_owner): "
                          "stop that owner, then run set without --no-claim");
  const double state = drive_state(client);
  if (state == static_cast<double>(reg::DriveState::enabled)) return;
  throw ClientError(Kind::refused_locally,
                    "refused, nothing sent: --no-claim needs a drive enabled by this line's "
                    "master, and this one is not (drive_state " +
                        op::code_name(reg::drive_states(), state) +
                        "): drop --no-claim (set claims control itself), or enable first");
}

/// The release after Ctrl-C, in words. A release that fails (another client took control
/// meanwhile) is said, not thrown: the command was still interrupted, and its exit code says so.
std::string release_after_interrupt(op::Client& client, reg::Mode mode) {
  try {
    return "control released (" + release(client, mode == reg::Mode::force) + ")";
  } catch (const ClientError& e) {
    return std::string("control not released: ") + e.what();
  }
}

struct SetOptions {
  std::string what, value, speed, accel;
  std::string unit;  // a unit typed apart from the number: "5 N", "5 kg"
};

/// "set force 5 N": the unit typed apart is read as "5N" (so "5 kg" is refused as "5kg" is, with
/// the units accepted); anything else after the value is refused with what to type.
void join_unit(SetOptions& o) {
  if (o.unit.empty()) return;
  const auto first = static_cast<unsigned char>(o.unit[0]);
  if (std::isalpha(first) == 0 && first < 0x80)
    throw ClientError(Kind::refused_locally,
                      "'" + o.unit + "' after '" + o.value +
                          "' was not expected: set takes one value, its unit right after the "
                          "number (e.g. 'maglead set force 5N')");
  o.value += o.unit;
}

/// A drive command, checked and ready to send: the mode the execute edge applies, its setpoints.
struct Planned {
  reg::Mode mode = reg::Mode::idle;
  std::vector<std::pair<std::string, double>> setpoints;
  std::string summary;
};

void refuse_locally_if(const std::optional<std::string>& why) {
  if (why) throw ClientError(Kind::refused_locally, "refused, nothing sent: " + *why);
}

const std::string& value_of(const SetOptions& o) {
  if (o.value.empty())
    throw ClientError(Kind::refused_locally,
                      "'set " + o.what +
                          "' needs a value (e.g. 'maglead set force 12.5', 'maglead set " +
                          "position 20mm'; 'maglead set --help' lists them)");
  return o.value;
}

bool is_bare_number(const std::string& text) {
  return !text.empty() && text.find_first_not_of("+-.0123456789eE ") == std::string::npos;
}

/// The usual unit a number typed without one may have been meant in ("mm", 1e-3 m).
struct UsualUnit {
  const char* unit;
  const char* name;
  double to_si;
};

/// A refusal of a number typed without a unit says which unit it was read in, and what to type
/// for the usual one when that is what was meant ("20" read as 20 m: "type '20mm' for
/// millimetres"): when the number read in the usual unit lies in [lo_si, hi_si], and read in SI
/// it is more than ten times the largest limit. A near miss (0.041 against a 0.040 m stroke end)
/// was meant in SI: 0.041 mm would be advice the person did not need.
std::optional<std::string> with_unit_hint(std::optional<std::string> why, const std::string& text,
                                          const char* si_unit, UsualUnit usual, double lo_si,
                                          double hi_si) {
  if (!why || !is_bare_number(text)) return why;
  *why += std::string("; a number without a unit is in ") + si_unit;
  const double si = op::parse_quantity(text, si_unit), in_usual = si * usual.to_si;
  constexpr double kNearMiss = 10.0;  // within this factor of the limits: meant in SI
  if (in_usual >= lo_si && in_usual <= hi_si &&
      std::abs(si) > kNearMiss * std::max(std::abs(lo_si), std::abs(hi_si)))
    *why += std::string(": type '") + text + usual.unit + "' for " + usual.name;
  return why;
}

/// The limits a setpoint is checked against: the controller's own (its limits block), else, from
/// a controller without the block, this machine's configuration.
op::Limits limits_of(op::Client& client, const CommandFlags& f) {
  op::Limits l;
  l.reported = op::read_reported_limits(client);
  if (!l.reported) return load_limits(f.config, f.calibration);
  l.actuator.stroke_min_m = l.reported->stroke_min_m;
  l.actuator.stroke_max_m = l.reported->stroke_max_m;
  return l;
}

Planned plan_force(const SetOptions& o, const op::Limits& limits) {
  const double force_n = op::parse_quantity(value_of(o), "N");
  refuse_locally_if(op::check_force(limits, force_n));
  char buf[64];
  std::snprintf(buf, sizeof buf, "force %.3f N", force_n);
  return {reg::Mode::force, {{"force_setpoint_mn", force_n}}, buf};
}

Planned plan_position(const SetOptions& o, const op::Limits& limits) {
  const double pos_m = op::parse_quantity(value_of(o), "m");
  const auto& a = limits.actuator;
  refuse_locally_if(with_unit_hint(op::check_position(limits, pos_m), o.value, "m",
                                   {"mm", "millimetres", 1e-3}, a.stroke_min_m, a.stroke_max_m));
  Planned p{reg::Mode::position, {{"position_setpoint_um", pos_m}}, {}};
  // The speed and acceleration limits, checked against their registers' ranges.
  const auto limit = [&](const std::string& text, const char* name, const char* si_unit,
                         UsualUnit usual) {
    const auto& r = *reg::find(name);
    const double v = op::parse_quantity(text, si_unit);
    refuse_locally_if(with_unit_hint(op::check_register(r, v), text, si_unit, usual, r.min, r.max));
    p.setpoints.emplace_back(name, v);
  };
  if (!o.speed.empty())
    limit(o.speed, "velocity_limit_um_s", "m/s", {"mm/s", "millimetres per second", 1e-3});
  if (!o.accel.empty())
    limit(o.accel, "accel_limit_um_s2", "m/s^2",
          {"mm/s^2", "millimetres per second squared", 1e-3});
  char buf[64];
  std::snprintf(buf, sizeof buf, "position %.3f mm", pos_m * 1e3);
  p.summary = buf;
  return p;
}

/// A register that holds a code takes its name as well as its number ("force", "reference-move").
std::optional<double> code_value(std::span<const reg::Code> codes, std::string text) {
  std::replace(text.begin(), text.end(), '-', '_');
  for (const auto& c : codes)
    if (c.name == text) return c.value;
  return std::nullopt;
}

/// What a plain write leaves to do: a staged setpoint (HR 1001, 1004-1019) acts only at the next
/// execute edge, and a watchdog shorter than the tools can feed stops set and enable. Else "".
std::string after_write_note(const reg::Register& r, double v) {
  const std::string name(r.name);
  const auto typed = [](double x, const char* unit) {
    char b[48];
    std::snprintf(b, sizeof b, "%g%s", x, unit);
    return std::string(b);
  };
  const std::string staged = " (staged: applied by the next execute; ";
  if (name.starts_with("force_setpoint"))
    return staged + "to apply a force now type 'maglead set force " + typed(v, "N") + "')";
  if (name.starts_with("position_setpoint"))
    return staged + "to move there now type 'maglead set position " + typed(v * 1e3, "mm") + "')";
  if (name.starts_with("velocity_limit") || name.starts_with("accel_limit"))
    return " (staged: the next move's limit, applied by its execute; 'maglead set position "
           "POSITION' moves at it now)";
  if (name == "mode_command")
    return staged + "to apply a mode now type 'maglead set force|position|idle|reference-move')";
  if (name == "watchdog_ms" && v > 0 && v < op::kShortestWatchdog_s)
    return "; note: set and enable cannot feed a watchdog shorter than " +
           typed(op::kShortestWatchdog_s, " s") +
           " and refuse to run while it is (a PLC can feed it); 'maglead set watchdog_s " +
           typed(op::kShortestWatchdog_s, "") + "' or 0 lets them";
  return {};
}

/// A plain register write (limits, watchdog …): checked, written, no execute edge.
void write_setting(const SetOptions& o, const CommandFlags& f, const ConnectionOptions& conn) {
  const std::string& text = value_of(o);
  const auto* r = op::find_by_any_name(o.what);  // the SI names poll prints, or register names
  if (!r) {
    std::vector<std::string> names{"force", "position", "idle", "reference-move"};
    for (const auto& x : reg::table())
      if (x.table == reg::Table::holding_register && x.access == reg::Access::read_write)
        names.push_back(op::si_name(x));
    const std::string guess = closest_match(o.what, names);
    throw ClientError(Kind::refused_locally,
                      "no register or setpoint named '" + o.what + "'" +
                          (guess.empty() ? "" : "; did you mean '" + guess + "'?") +
                          " ('maglead registers' lists them; 'maglead poll' shows the names)");
  }
  if (r->table != reg::Table::holding_register || r->access != reg::Access::read_write ||
      r->name == "control_word")
    throw ClientError(Kind::refused_locally, "'" + o.what +
                                                 "' is not a writable setting (use enable, "
                                                 "disable, reset or set force/position)");
  // The register's own name (watchdog_ms) names its raw unit: a bare number typed under it is
  // in that unit (watchdog_ms 50 is 0.05 s), as a PLC writes it; the SI name reads it in SI.
  const bool raw = o.what == r->name && op::si_name(*r) != r->name && is_bare_number(text);
  const auto codes = reg::codes_of(r->name);
  const auto code = code_value(codes, text);
  if (!codes.empty() && !code && !is_bare_number(text)) {
    std::string known;
    for (const auto& c : codes)
      known += (known.empty() ? "" : ", ") + std::to_string(c.value) + " " + std::string(c.name);
    throw ClientError(Kind::refused_locally, "refused, nothing sent: '" + text + "' is not a " +
                                                 std::string(r->name) + " code: " + known);
  }
  const double v = code ? *code : op::parse_quantity(text, r->unit) * (raw ? r->scale : 1.0);
  const std::string raw_note = raw ? " (" + o.what + " " + text +
                                         ": a number without a unit is in the raw unit the " +
                                         "register name says)"
                                   : "";
  if (auto why = op::check_register(*r, v)) refuse_locally_if(*why + raw_note);
  op::Client client(endpoint_of(conn));
  client.check_identity();
  if (r->name.starts_with("force_setpoint"))
    refuse_locally_if(op::check_force(limits_of(client, f), v));
  if (r->name.starts_with("position_setpoint"))
    refuse_locally_if(op::check_position(limits_of(client, f), v));
  client.write({{std::string(r->name), v}});
  // A code is said with its name ("mode_command = 2 (force)"), a quantity with its unit.
  const std::string unit_or_name = !codes.empty()
                                       ? " (" + op::code_name(codes, v) + ")"
                                       : (r->unit.empty() ? "" : " " + std::string(r->unit));
  print_line(op::si_name(*r) + " = " + op::si_text(*r, v) + unit_or_name + " written" + raw_note +
             after_write_note(*r, v));
}

// A move or a force that takes longer than this gets a progress line; a quick one none (no
// flicker on a short move).
constexpr double kProgressAfter_s = 0.5;
// The line is redrawn at most this often: readable, and one extra read per redraw only.
constexpr double kProgressPeriod_s = 0.2;

/// The progress line while execute waits for done, from the controller's own nut position and
/// force estimate: "moving to 20.000 mm: nut at 12.345 mm, 7.7 mm to go".
std::function<void(op::Client&)> progress_of(const Planned& p, StatusLine& line) {
  if (!line.enabled() || p.setpoints.empty()) return {};
  const auto t0 = std::chrono::steady_clock::now();
  auto last = t0 - std::chrono::hours(1);
  const double target = p.setpoints.front().second;
  const bool force = p.mode == reg::Mode::force;
  return [&line, t0, last, target, force](op::Client& c) mutable {
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - t0).count() < kProgressAfter_s ||
        std::chrono::duration<double>(now - last).count() < kProgressPeriod_s)
      return;
    last = now;
    const auto* pos = reg::find("nut_pos_um");
    const auto* est = reg::find("force_est_mn");
    const auto v = c.read_range(reg::Table::input_register, pos->address,
                                static_cast<std::uint16_t>(est->address + 2 - pos->address));
    const double nut_m = v.at("nut_pos_um"), force_n = v.at("force_est_mn");
    char b[128];
    if (force)
      std::snprintf(b, sizeof b, "reaching %.3f N: nut at %.3f mm, force estimate %.1f N", target,
                    nut_m * 1e3, force_n);
    else
      std::snprintf(b, sizeof b, "moving to %.3f mm: nut at %.3f mm, %.1f mm to go", target * 1e3,
                    nut_m * 1e3, std::abs(target - nut_m) * 1e3);
    line.show(b);
  };
}

/// The controller's own limits, read from its limits block (what it refused against); this
/// machine's configuration may differ from the one the controller runs.
std::string drive_limit_text(op::Client& client, reg::Mode mode) {
  op::Limits limits;
  limits.reported = op::read_reported_limits(client);
  if (!limits.reported) return "not reported (its register map has no limits block)";
  return mode == reg::Mode::force ? op::force_limit_text(limits) : op::position_limit_text(limits);
}

/// Sends the command. The controller's own limit refusing it (exception 03 on the staged
/// setpoint, or a reject reason) is said with the value and the limit the controller reports.
op::CommandResult send(op::Client& client, const Planned& p, const CommandFlags& f,
                       StatusLine& line) {
  op::CommandOptions options = f.options();
  options.stop = [] { return g_interrupted != 0; };
  options.waiting = progress_of(p, line);
  try {
    return op::execute(client, p.mode, p.setpoints, options);
  } catch (const ClientError& e) {
    const std::string msg = e.what();
    // Only the controller's force or stroke limit is worth the limit text: an exception 03 for a
    // register's range (out_of_range) names that register itself, and the stroke beside it would
    // blame a position that was inside.
    const bool limit = (e.kind() == Kind::exception || e.kind() == Kind::rejected) &&
                       (msg.find("force_beyond_safe_limit") != std::string::npos ||
                        msg.find("position_outside_stroke") != std::string::npos ||
                        msg.find("target_outside_stroke") != std::string::npos);
    if (!limit || p.mode == reg::Mode::idle) throw;
    throw ClientError(e.kind(), p.summary + " refused by the controller (" + msg +
                                    "); its limits are " + drive_limit_text(client, p.mode));
  }
}

/// send, and when it fails after this client may have claimed control, release it before the
/// error is reported: a failed command leaves no owner-loss fault behind.
op::CommandResult send_or_release(op::Client& client, const Planned& p, const CommandFlags& f) {
  StatusLine line;
  try {
    return send(client, p, f, line);
  } catch (const ClientError& e) {
    line.clear();
    if (f.no_claim || e.kind() == Kind::refused_locally || e.kind() == Kind::connection) throw;
    // A latched fault has stopped the drive already: there is nothing to bring to 0 N, and only a
    // reset clears it.
    std::optional<double> alarm;
    std::string advice;
    try {
      alarm = fault_alarm(client);
      if (alarm) advice = op::reset_advice(client, *alarm);
    } catch (const ClientError&) {
      throw e;  // the line went too: the command's own error is the one to say
    }
    if (alarm) {
      const std::string what = e.what();
      throw ClientError(e.kind(), what.find("maglead reset") == std::string::npos
                                      ? what + "; the drive is in fault: " + advice
                                      : what);
    }
    std::string done;
    try {
      done = release(client, p.mode == reg::Mode::force, e.what());
    } catch (const ClientError&) {
      throw e;  // not the owner (or gone): nothing to release
    }
    throw ClientError(e.kind(), std::string(e.what()) + "; control released (" + done + ")");
  }
}

void run_set(SetOptions o, const CommandFlags& f, const ConnectionOptions& conn) {
  join_unit(o);
  catch_interrupt();  // Ctrl-C at any time ends in a clean release, never a vanished owner
  const bool force = o.what == "force", position = o.what == "position";
  const bool reference = o.what == "reference-move" || o.what == "reference_move";
  if (!force && !position && !reference && o.what != "idle") {
    write_setting(o, f, conn);
    return;
  }
  // What can be checked without the controller is, before a connection is opened: the value's
  // unit, --hold, --wait; the limits are the controller's own, read from it.
  if (force || position) op::parse_quantity(value_of(o), force ? "N" : "m");
  if (!f.hold.empty()) parse_duration_s(f.hold, "--hold");
  parse_duration_s(f.wait, "--wait");
  if (reference && f.no_wait && f.hold.empty())
    throw ClientError(Kind::refused_locally,
                      "set reference-move --no-wait would keep control until Ctrl-C: drop "
                      "--no-wait (it returns once the move is done, control released) or add "
                      "--hold DURATION");
  op::Client client(endpoint_of(conn));
  client.check_identity();
  Planned p{reg::Mode::idle, {}, "idle (stop and hold)"};
  if (force || position) {
    const op::Limits limits = limits_of(client, f);
    p = force ? plan_force(o, limits) : plan_position(o, limits);
  } else if (reference) {
    // The configured back-and-forth ([reference_move]): the drift flag's free moves on demand.
    p = {reg::Mode::reference_move, {}, "reference move (mode_command 3)"};
  }
  if (f.no_claim) refuse_no_claim_unless_enabled(client);
  const op::CommandResult res = send_or_release(client, p, f);
  if (res.done)
    print_line(p.summary + ": done (" +
               (p.mode == reg::Mode::force ? "force reached" : "in position") + ") after " +
               fixed(res.elapsed_s, 2) + " s");
  else if (g_interrupted) {  // not done: no "holding" follows, the exit code says so
    fresh_line_after_interrupt(g_interrupted);
    throw ClientError(
        Kind::interrupted,
        p.summary + ": acknowledged, interrupted before done" +
            (f.no_claim ? std::string() : "; " + release_after_interrupt(client, p.mode)));
  } else
    print_line(p.summary + ": acknowledged by the controller");
  // A claimed control is held, then released; without a claim this client owns nothing. A
  // reference move is a task with an end: done, it lets go (a script calling it returns).
  if (!f.no_claim && p.mode == reg::Mode::reference_move && f.hold.empty() && res.done)
    print_line("released: " + release(client, false) +
               " (the move is over; --hold keeps control after it)");
  else if (!f.no_claim)
    hold_then_release(client, f.hold, f.options(), p.summary, p.mode == reg::Mode::force,
                      "maglead set " + o.what + (o.value.empty() ? "" : " " + o.value));
}

void add_set(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "set",
      "Apply a setpoint: 'set force 12.5' [N], 'set position 20mm', 'set idle' (stop and hold), "
      "'set reference-move' (the configured back-and-forth the drift flag learns from), or 'set "
      "NAME VALUE' for a writable holding register (e.g. watchdog_s 0.5s)");
  auto conn = add_connection_options(cmd);
  auto f = std::make_shared<CommandFlags>();
  auto o = std::make_shared<SetOptions>();
  cmd->add_option("what", o->what, "force, position, idle, reference-move, or a register name");
  // Not ->required(): CLI11 would say "what is required", the positional's name in this file.
  cmd->parse_complete_callback([o] {
    if (o->what.empty())
      throw CLI::RequiredError(
          "say what to set: maglead set force|position|idle|reference-move|SETTING [VALUE] (e.g. "
          "'maglead set force 12.5', 'maglead set position 20mm', 'maglead set watchdog_s 0.5s')",
          CLI::ExitCodes::RequiredError);
  });
  cmd->add_option("value", o->value,
                  "Value with optional unit: 12.5, 12.5N, 20mm, 0.02m (a bare number is in SI "
                  "units, N or m; under a raw register name such as watchdog_ms, in its unit)");
  cmd->add_option("unit", o->unit, "A unit typed apart from the number: '5 N' reads as 5N");
  cmd->add_option("--speed", o->speed,
                  "Position moves: speed limit (e.g. 5mm/s; default: the one staged in the "
                  "controller, velocity_limit_m_s, 10 mm/s at start)");
  cmd->add_option("--accel", o->accel,
                  "Position moves: acceleration limit (e.g. 0.1m/s^2; default: the one staged, "
                  "accel_limit_m_s2, 0.1 m/s^2 at start)");
  add_command_flags(cmd, f, true);
  cmd->add_option("--hold", f->hold, kHoldHelp);
  cmd->add_flag("--no-claim", f->no_claim,
                "Do not take control (by default: clear an owner_lost fault and enable when nobody "
                "owns the drive)");
  cmd->callback([o, f, conn] { run_operator("set", [&] { run_set(*o, *f, *conn); }); });
}

/// A command that connects, checks the identity and runs one step of the drive's state machine.
template <class Step>
void add_drive_command(CLI::App& app, const char* name, const char* help, Step step) {
  auto* cmd = app.add_subcommand(name, help);
  auto conn = add_connection_options(cmd);
  auto resync = std::make_shared<bool>(false);
  auto hold = std::make_shared<std::string>();
  if (std::string_view(name) == "reset")
    cmd->add_flag("--resync", *resync,
                  "First re-synchronise the phase (after a step-out: the nut's new lead is zero)");
  if (std::string_view(name) == "enable") cmd->add_option("--hold", *hold, kHoldHelp);
  const bool holds = std::string_view(name) == "enable";
  cmd->callback([conn, resync, hold, name, step, holds] {
    run_operator(name, [&] {
      if (!hold->empty()) parse_duration_s(*hold, "--hold");
      if (holds) catch_interrupt();
      op::Client client(endpoint_of(*conn));
      client.check_identity();
      print_line(step(client, *resync));
      if (holds) hold_then_release(client, *hold, {}, "control", false, "maglead enable");
    });
  });
}

void add_enable(CLI::App& app) {
  add_drive_command(
      app, "enable",
      "Claim control and enable a ready drive (rising edge of the enable bit); keeps control "
      "until Ctrl-C (or --hold), then disables the drive cleanly",
      [](op::Client& c, bool) {
        op::enable(c, {});
        return std::string("drive enabled");
      });
}
void add_disable(CLI::App& app) {
  add_drive_command(app, "disable",
                    "Disable the drive (falling edge of the enable bit) and release control",
                    [](op::Client& c, bool) { return op::disable_and_say(c); });
}
void add_reset(CLI::App& app) {
  add_drive_command(app, "reset", "Clear a latched fault (fault_reset edge, ack/done handshake)",
                    [](op::Client& c, bool resync) { return op::reset_and_say(c, resync); });
}

MAGLEAD_COMMAND(81, add_set);
MAGLEAD_COMMAND(82, add_enable);
MAGLEAD_COMMAND(83, add_disable);
MAGLEAD_COMMAND(84, add_reset);

}  // namespace
}  // namespace maglead::cli
