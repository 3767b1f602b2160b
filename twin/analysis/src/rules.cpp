// The rule table as Markdown (`maglead analysis-rules`, docs/analysis.md) and the tests it names.
#include "maglead/analysis/rules.hpp"

#include <algorithm>
#include <cstdio>
#include <vector>

namespace maglead::analysis::rules {

std::string rules_markdown() {
  std::string out =
      "| stage | rule | value | unit | why | pinned by |\n"
      "|---|---|---|---|---|---|\n";
  for (const auto& r : kTable) {
    char value[32];
    std::snprintf(value, sizeof value, "%g", r.value);
    out += "| " + std::string(r.stage) + " | `" + std::string(r.name) + "` | " + value + " | " +
           std::string(r.unit) + " | " + std::string(r.why) + " | `" + std::string(r.test) +
           "` |\n";
  }
  return out;
}

std::string rules_tests() {
  std::vector<std::string_view> tests;
  tests.reserve(kTable.size());
  for (const auto& r : kTable) tests.push_back(r.test);
  std::sort(tests.begin(), tests.end());
  tests.erase(std::unique(tests.begin(), tests.end()), tests.end());
  std::string out;
  for (const auto t : tests) out += std::string(t) + "\n";
  return out;
}

}  // namespace maglead::analysis::rules
