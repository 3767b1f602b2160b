// maglead analysis-rules: print the analysis's decision rules (docs/analysis.md's "How it
// decides" table is this command's output).
#include <cstdio>

#include "cli_common.hpp"
#include "maglead/analysis/rules.hpp"

namespace maglead::cli {
namespace {

void add_analysis_rules(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "analysis-rules", "Print the analysis's decision thresholds (md) or the tests they name");
  auto format = std::make_shared<std::string>("md");
  cmd->add_option("--format", *format, "Output format (tests: the ctest tests the table names)")
      ->check(CLI::IsMember({"md", "tests"}))
      ->capture_default_str();
  cmd->callback([format] {
    const std::string text =
        *format == "md" ? analysis::rules::rules_markdown() : analysis::rules::rules_tests();
    std::fwrite(text.data(), 1, text.size(), stdout);
  });
}

MAGLEAD_COMMAND(61, add_analysis_rules);

}  // namespace
}  // namespace maglead::cli
