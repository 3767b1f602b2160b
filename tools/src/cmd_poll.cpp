// maglead poll: read a controller's registers once over Modbus and print them by name, in SI
// units (table, JSON or CSV), with status bits, alarm and drive state spelled out.
#include <algorithm>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>

#include "operator_cli.hpp"

namespace maglead::cli {
namespace {

namespace reg = maglead::registers;

std::string value_text(const reg::Register& r, double v) {
  char b[64];
  if (r.type == reg::Type::f32 || r.scale != 1.0) std::snprintf(b, sizeof b, "%.9g", v);
  else std::snprintf(b, sizeof b, "%.0f", v);
  return b;
}

/// What a code register means, for the table's last column.
std::string meaning(const reg::Register& r, double v) {
  if (r.name == "status_word") {
    std::string s;
    for (const auto& n : op::status_bits(static_cast<std::uint16_t>(v))) s += (s.empty() ? "" : " ") + n;
    return s.empty() ? "(no bits set)" : s;
  }
  if (r.name == "alarm_code") return op::code_name(reg::alarm_codes(), v) + ": " + op::code_meaning(reg::alarm_codes(), v);
  if (r.name == "command_reject_reason") return op::code_name(reg::reject_codes(), v);
  if (r.name == "drive_state") return op::code_name(reg::drive_states(), v);
  if (r.name == "active_mode" || r.name == "mode_command") return op::code_name(reg::modes(), v);
  if (r.name == "device_type") {
    char b[32];
    std::snprintf(b, sizeof b, "0x%04X%s", static_cast<unsigned>(v), v == reg::kDeviceType ? " (maglead)" : "");
    return b;
  }
  if (r.name == "control_owner_ipv4" && v != 0) {
    const auto a = static_cast<std::uint32_t>(v);
    return std::to_string(a >> 24) + "." + std::to_string((a >> 16) & 255) + "." + std::to_string((a >> 8) & 255) +
           "." + std::to_string(a & 255);
  }
  if (r.name == "control_owner") return v == 0 ? "nobody" : v == 65535 ? "the RTU master" : "TCP connection";
  if (r.name == "control_word") {
    std::string s;
    for (const auto& c : reg::table())
      if (c.table == reg::Table::coil && ((static_cast<unsigned>(v) >> c.address) & 1u))
        s += (s.empty() ? "" : " ") + std::string(c.name);
    return s;
  }
  return "";
}

void add_poll(CLI::App& app) {
  auto* cmd = app.add_subcommand("poll", "Read a maglead controller's registers once (Modbus TCP or RTU) and "
                                         "print them by name in SI units");
  auto conn = add_connection_options(cmd);
  struct Opts {
    bool json = false, csv = false, raw = false, all = false;
    std::vector<std::string> names;
  };
  auto o = std::make_shared<Opts>();
  auto* fmt = cmd->add_option_group("Output format");
  fmt->add_flag("--json", o->json, "JSON: {\"values\": {name: value}, \"units\": …, \"status_bits\": …}");
  fmt->add_flag("--csv", o->csv, "CSV: name,value,unit");
  fmt->require_option(0, 1);
  cmd->add_flag("--raw", o->raw, "Raw register contents (integers as sent) instead of SI values");
  cmd->add_flag("--all", o->all, "Also the float32 duplicates and identity probes");
  cmd->add_option("--names", o->names, "Only these registers (names from 'maglead registers')")->delimiter(',');
  cmd->callback([o, conn] {
    run_operator("poll", [&] {
      for (const auto& n : o->names)
        if (!reg::find(n)) throw op::ClientError(op::ClientError::Kind::refused_locally, "no register named '" + n + "'");
      op::Client client(endpoint_of(*conn));
      client.check_identity();
      const auto v = client.read_tables({reg::Table::input_register, reg::Table::holding_register});
      std::vector<std::size_t> shown;  // --names order if given, else the table's
      if (!o->names.empty()) {
        for (const auto& n : o->names)
          for (std::size_t i = 0; i < v.regs.size(); ++i)
            if (v.regs[i]->name == n) shown.push_back(i);
      } else {
        for (std::size_t i = 0; i < v.regs.size(); ++i) {
          const auto& r = *v.regs[i];
          if (!o->all && (r.type == reg::Type::f32 || r.name.starts_with("word_order_probe"))) continue;
          shown.push_back(i);
        }
      }
      const auto value_of = [&](std::size_t i) { return o->raw ? static_cast<double>(v.raw[i]) : v.si[i]; };
      if (o->json) {
        nlohmann::ordered_json j, vals = nlohmann::ordered_json::object(), units = nlohmann::ordered_json::object();
        for (auto i : shown) {
          vals[std::string(v.regs[i]->name)] = value_of(i);
          units[std::string(v.regs[i]->name)] = o->raw ? "raw" : std::string(v.regs[i]->unit);
        }
        j["controller"] = client.endpoint().describe();
        j["values"] = vals;
        j["units"] = units;
        const auto sw = static_cast<std::uint16_t>(v.at("status_word"));
        j["status_bits"] = op::status_bits(sw);
        j["drive_state"] = op::code_name(reg::drive_states(), v.at("drive_state"));
        j["alarm"] = {{"code", v.at("alarm_code")},
                      {"name", op::code_name(reg::alarm_codes(), v.at("alarm_code"))},
                      {"meaning", op::code_meaning(reg::alarm_codes(), v.at("alarm_code"))}};
        std::printf("%s\n", j.dump(2).c_str());
      } else if (o->csv) {
        std::printf("name,value,unit\n");
        for (auto i : shown)
          std::printf("%s,%s,%s\n", std::string(v.regs[i]->name).c_str(),
                      o->raw ? std::to_string(v.raw[i]).c_str() : value_text(*v.regs[i], v.si[i]).c_str(),
                      o->raw ? "raw" : std::string(v.regs[i]->unit).c_str());
      } else {
        std::printf("%s\n", client.endpoint().describe().c_str());
        for (auto i : shown) {
          const auto& r = *v.regs[i];
          std::printf("  %-28s %16s %-6s %s\n", std::string(r.name).c_str(),
                      o->raw ? std::to_string(v.raw[i]).c_str() : value_text(r, v.si[i]).c_str(),
                      o->raw ? "raw" : std::string(r.unit).c_str(), meaning(r, v.si[i]).c_str());
        }
      }
    });
  });
}

MAGLEAD_COMMAND(80, add_poll);

}  // namespace
}  // namespace maglead::cli
