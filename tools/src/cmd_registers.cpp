// maglead registers: print the register map (docs/registers.md is this command's output).
#include <cstdio>

#include "cli_common.hpp"
#include "maglead/registers/registers.hpp"

namespace maglead::cli {
namespace {

void add_registers(CLI::App& app) {
  auto* cmd = app.add_subcommand("registers", "Print the Modbus register map (md, csv or json)");
  auto format = std::make_shared<std::string>("md");
  cmd->add_option("--format", *format, "Output format")
      ->check(CLI::IsMember({"md", "csv", "json"}))
      ->capture_default_str();
  cmd->callback([format] {
    const std::string text = *format == "md"    ? registers::to_markdown()
                             : *format == "csv" ? registers::to_csv()
                                                : registers::to_json();
    std::fwrite(text.data(), 1, text.size(), stdout);
  });
}

MAGLEAD_COMMAND(60, add_registers);

}  // namespace
}  // namespace maglead::cli
