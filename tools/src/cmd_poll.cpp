// maglead poll: read a controller's registers once over Modbus and print them by name, in SI
// units (table, JSON or CSV), with status bits, alarm and drive state spelled out.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>

#include "operator_cli.hpp"

namespace maglead::cli {
namespace {

namespace reg = maglead::registers;

/// The load cell's integer register reads 0 on a backend without one; its float32 copy is NaN.
bool no_load_cell(const reg::Register& r, const op::Values& all) {
  return r.name == "load_cell_force_mn" && !op::has_load_cell(all);
}

/// command_status's bits by name (registers.hpp CommandBit): "execute_done reset_done rejected".
std::string command_bits_text(std::uint16_t word) {
  std::string s;
  for (const auto& name : op::command_bits(word)) s += (s.empty() ? "" : " ") + name;
  return s.empty() ? "(no bits set)" : s;
}

/// What a code register means, for the table's last column; `all` holds every register read.
std::string meaning(const reg::Register& r, double v, const op::Values& all) {
  // The SI value itself reads "none" (Shown::text), --raw the 0 sent: neither is a 0 N reading.
  if (no_load_cell(r, all))
    return "no load cell on this backend (the register reads 0, not a force)";
  if (r.name == "status_word") {
    std::string s;
    for (const auto& n : op::status_bits(static_cast<std::uint16_t>(v)))
      s += (s.empty() ? "" : " ") + n;
    return s.empty() ? "(no bits set)" : s;
  }
  if (r.name == "command_status") return command_bits_text(static_cast<std::uint16_t>(v));
  if (r.name == "alarm_code")
    return op::code_name(reg::alarm_codes(), v) + ": " + op::code_meaning(reg::alarm_codes(), v);
  if (const auto codes = reg::codes_of(r.name); !codes.empty()) return op::code_name(codes, v);
  if (r.name == "device_type") {
    char b[32];
    std::snprintf(b, sizeof b, "0x%04X%s", static_cast<unsigned>(v),
                  v == reg::kDeviceType ? " (maglead)" : "");
    return b;
  }
  // A figure the twin has not formed yet reads 0: said, so 0 is not taken for a measurement.
  if (v == 0.0 && (r.name == "twin_gain_f32" || r.name == "twin_gain_stderr_f32" ||
                   r.name == "twin_gain_reference_f32"))
    return "not estimated yet";
  if (r.name == "drive_error_code" && v != 0) {
    char b[48];
    std::snprintf(b, sizeof b, "0x%04X (the drive's manual)", static_cast<unsigned>(v));
    return b;
  }
  if (r.name == "control_owner_ipv4" && v != 0) {
    const auto a = static_cast<std::uint32_t>(v);
    return std::to_string(a >> 24) + "." + std::to_string((a >> 16) & 255) + "." +
           std::to_string((a >> 8) & 255) + "." + std::to_string(a & 255);
  }
  if (r.name == "control_owner")
    return v == 0 ? "nobody" : v == 65535 ? "the RTU master" : "TCP connection";
  if (r.name == "control_word") {
    std::string s;
    for (const auto& c : reg::table())
      if (c.table == reg::Table::coil && ((static_cast<unsigned>(v) >> c.address) & 1u))
        s += (s.empty() ? "" : " ") + std::string(c.name);
    return s;
  }
  return "";
}

/// A raw value as a PLC reads it: signed types signed (an INT/DINT of -318, not 4294966978),
/// float32 as its bit pattern.
std::string raw_text(const reg::Register& r, std::uint32_t raw_word) {
  if (r.type == reg::Type::i32) return std::to_string(static_cast<std::int32_t>(raw_word));
  if (r.type == reg::Type::i16)
    return std::to_string(static_cast<std::int16_t>(static_cast<std::uint16_t>(raw_word)));
  return std::to_string(raw_word);
}

/// The JSON literal of one value: the raw integer, or the SI value at the register's resolution
/// in plain decimals. nlohmann writes doubles below 1e-4 with an exponent (0.000071 s as
/// 7.1e-05), so fixed-point registers are written here from si_text (%.*f, zeros trimmed).
std::string json_literal(const reg::Register& r, double si, std::uint32_t raw_word, bool raw) {
  if (raw) return raw_text(r, raw_word);
  if (!std::isfinite(si)) return "null";
  if (r.type == reg::Type::f32) return nlohmann::json(op::si_rounded(r, si)).dump();
  if (op::si_decimals(r) == 0) return nlohmann::json(std::llround(si)).dump();
  return op::si_text(r, si);
}

struct PollOptions {
  bool json = false, csv = false, raw = false, all = false;
  std::vector<std::string> names;
};

/// The registers --names asks for, each by its register or SI name; an unknown name is refused
/// (with the closest known one) before anything is sent. The name suggested is of the kind poll
/// shows, SI (nut_pos_m) or under --raw the register's (nut_pos_um): the one the user would type.
std::vector<const reg::Register*> wanted_registers(const std::vector<std::string>& names,
                                                   bool raw) {
  std::vector<const reg::Register*> wanted;
  for (const auto& n : names) {
    const auto* r = op::find_by_any_name(n);
    if (!r) {
      std::vector<std::string> all;  // the kind shown first: a prefix matches the first it meets
      for (const auto& x : reg::table()) all.push_back(raw ? std::string(x.name) : op::si_name(x));
      for (const auto& x : reg::table()) all.push_back(raw ? op::si_name(x) : std::string(x.name));
      const std::string guess = closest_match(n, all);
      throw op::ClientError(op::ClientError::Kind::refused_locally,
                            "no register named '" + n + "'" +
                                (guess.empty() ? "" : "; did you mean '" + guess + "'?") +
                                " ('maglead registers' lists them)");
    }
    wanted.push_back(r);
  }
  return wanted;
}

/// A float32 register that repeats an integer one (nut_pos_m_f32 beside nut_pos_um): si_name
/// keeps its suffix; the float32-only ones (the drift flag's figures) lose it and are shown.
bool is_float_duplicate(const reg::Register& r) {
  return r.type == reg::Type::f32 && r.name.ends_with("_f32") && op::si_name(r) == r.name;
}

/// Indices into v of what is shown: --names order if given, else the table's.
std::vector<std::size_t> shown_indices(const op::Values& v,
                                       const std::vector<const reg::Register*>& wanted, bool all) {
  std::vector<std::size_t> shown;
  if (!wanted.empty()) {
    for (const auto* w : wanted)
      for (std::size_t i = 0; i < v.regs.size(); ++i)
        if (v.regs[i] == w) shown.push_back(i);
    return shown;
  }
  for (std::size_t i = 0; i < v.regs.size(); ++i) {
    const auto& r = *v.regs[i];
    if (!all && (is_float_duplicate(r) || r.name.starts_with("word_order_probe"))) continue;
    shown.push_back(i);
  }
  return shown;
}

/// What is printed: SI values under SI names (nut_pos_m), raw integers under the register names
/// (nut_pos_um).
struct Shown {
  const op::Values& v;
  std::vector<std::size_t> idx;
  bool raw;
  bool csv = false;  // a value there is not: CSV's empty field, the table's "none"
  std::string name(std::size_t i) const {
    return raw ? std::string(v.regs[i]->name) : op::si_name(*v.regs[i]);
  }
  /// No load cell (cia402): not a reading of 0 N. --raw keeps the integer as sent, 0.
  bool none(std::size_t i) const { return !raw && no_load_cell(*v.regs[i], v); }
  std::string text(std::size_t i) const {
    if (none(i)) return csv ? "" : "none";
    return raw ? raw_text(*v.regs[i], v.raw[i]) : op::si_text(*v.regs[i], v.si[i]);
  }
  std::string unit(std::size_t i) const {
    if (none(i) && !csv) return "";
    return raw ? "raw" : std::string(v.regs[i]->unit);
  }
};

void print_json(const Shown& s, const op::Client& client) {
  // "values" is written by hand (json_literal) and put in place of a marker after dump().
  static const std::string kMarker = "\"values\": \"@values@\"";
  std::string vals = s.idx.empty() ? "\"values\": {}" : "\"values\": {";
  nlohmann::ordered_json j, units = nlohmann::ordered_json::object();
  for (auto i : s.idx) {
    vals += std::string(vals.back() == '{' ? "" : ",") + "\n    " +
            nlohmann::json(s.name(i)).dump() + ": " +
            (no_load_cell(*s.v.regs[i], s.v) && !s.raw
                 ? "null"
                 : json_literal(*s.v.regs[i], s.v.si[i], s.v.raw[i], s.raw));
    units[s.name(i)] = s.unit(i);
  }
  if (!s.idx.empty()) vals += "\n  }";
  const op::Values& v = s.v;
  j["controller"] = client.endpoint().describe();
  j["values"] = "@values@";
  j["units"] = units;
  j["status_bits"] = op::status_bits(static_cast<std::uint16_t>(v.at("status_word")));
  j["drive_state"] = op::code_name(reg::drive_states(), v.at("drive_state"));
  j["alarm"] = {{"code", std::llround(v.at("alarm_code"))},
                {"name", op::code_name(reg::alarm_codes(), v.at("alarm_code"))},
                {"meaning", op::code_meaning(reg::alarm_codes(), v.at("alarm_code"))}};
  std::string text = j.dump(2);
  text.replace(text.find(kMarker), kMarker.size(), vals);
  std::printf("%s\n", text.c_str());
}

void print_csv(const Shown& s) {
  std::printf("name,value,unit\n");
  for (auto i : s.idx)
    std::printf("%s,%s,%s\n", s.name(i).c_str(), s.text(i).c_str(), s.unit(i).c_str());
}

/// The table for a person: on a terminal a long meaning wraps under its own column; into a pipe
/// each register stays one line (scripts grep it).
void print_table(const Shown& s, const op::Client& client) {
  print_line(client.endpoint().describe());
  int width = 0;  // the longest name shown: values line up whatever --all adds
  for (auto i : s.idx) width = std::max(width, static_cast<int>(s.name(i).size()));
  constexpr int kValue = 12, kUnit = 6;
  const int meaning_column = 2 + width + 1 + kValue + 1 + kUnit + 1;
  for (auto i : s.idx) {
    char head[160];
    std::snprintf(head, sizeof head, "  %-*s %*s %-*s ", width, s.name(i).c_str(), kValue,
                  s.text(i).c_str(), kUnit, s.unit(i).c_str());
    print_line(head + meaning(*s.v.regs[i], s.v.si[i], s.v),
               static_cast<std::size_t>(meaning_column));
  }
}

void run_poll(const PollOptions& o, const ConnectionOptions& conn) {
  const auto wanted = wanted_registers(o.names, o.raw);
  op::Client client(endpoint_of(conn));
  client.check_identity();
  const auto v = client.read_tables({reg::Table::input_register, reg::Table::holding_register});
  const Shown s{v, shown_indices(v, wanted, o.all), o.raw, o.csv};
  if (o.json)
    print_json(s, client);
  else if (o.csv)
    print_csv(s);
  else
    print_table(s, client);
}

void add_poll(CLI::App& app) {
  auto* cmd =
      app.add_subcommand("poll",
                         "Read a maglead controller's registers once (Modbus TCP or RTU) and "
                         "print them by name in SI units");
  auto conn = add_connection_options(cmd);
  auto o = std::make_shared<PollOptions>();
  auto* fmt = cmd->add_option_group("Output format");
  fmt->add_flag(
      "--json", o->json,
      "JSON: {\"values\": {name: value}, \"units\": …, \"status_bits\": …}; values rounded to the "
      "register's resolution");
  fmt->add_flag("--csv", o->csv, "CSV: name,value,unit");
  fmt->require_option(0, 1);
  cmd->add_flag(
      "--raw", o->raw,
      "Raw register contents (integers as sent) under the register names (nut_pos_um in um), "
      "instead of SI values under SI names (nut_pos_m in m)");
  cmd->add_flag("--all", o->all,
                "Also the float32 copies of integer registers and the word-order probes");
  cmd->add_option("names,--names", o->names,
                  "Only these registers: register names from 'maglead registers' or their SI names "
                  "(nut_pos_um or nut_pos_m), e.g. 'maglead poll nut_pos_m force_est_n'")
      ->delimiter(',');
  cmd->callback([o, conn] { run_operator("poll", [&] { run_poll(*o, *conn); }); });
}

MAGLEAD_COMMAND(80, add_poll);

}  // namespace
}  // namespace maglead::cli
