// The analysis's rule table (issue 43): every rule named once, with a unit, a why, a test and a
// known stage; docs/analysis.md's "How it decides" table is the table's Markdown.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <string>

#include "maglead/analysis/rules.hpp"

namespace rules = maglead::analysis::rules;

TEST(RuleTable, NamesUniqueUnitsWhysTestsAndStagesGivenValuesFinite) {
  std::set<std::string_view> names;
  for (const auto& r : rules::kTable) {
    SCOPED_TRACE(std::string(r.name));
    EXPECT_FALSE(r.name.empty());
    EXPECT_TRUE(names.insert(r.name).second) << "two rules share this name";
    EXPECT_TRUE(std::isfinite(r.value));
    EXPECT_FALSE(r.unit.empty());
    EXPECT_FALSE(r.why.empty());
    EXPECT_FALSE(r.test.empty());
    EXPECT_NE(std::find(rules::kStages.begin(), rules::kStages.end(), r.stage),
              rules::kStages.end());
    // One line each: the Markdown row must not break.
    EXPECT_EQ(r.why.find_first_of("|\n"), std::string_view::npos);
    EXPECT_EQ(r.unit.find_first_of("|\n"), std::string_view::npos);
  }
}

TEST(RuleTable, NamedConstantsAreTheTablesValues) {
  const auto value = [](std::string_view name) {
    for (const auto& r : rules::kTable)
      if (r.name == name) return r.value;
    return std::numeric_limits<double>::quiet_NaN();
  };
  EXPECT_EQ(rules::kMinHeldOutGainPct, value("min_held_out_gain_pct"));
  EXPECT_EQ(rules::kMinT, value("min_t"));
  EXPECT_EQ(rules::kParsimony, value("parsimony"));
  EXPECT_EQ(rules::kBreakawaySigmas, value("breakaway_sigmas"));
  EXPECT_EQ(static_cast<double>(rules::kTwinCheckBlocks), value("twin_check_blocks"));
  EXPECT_EQ(static_cast<double>(rules::kMinSlidingSamples), value("min_sliding_samples"));
}

TEST(RuleTable, DocsHowItDecidesIsTheTable) {
  std::ifstream in(MAGLEAD_ANALYSIS_DOC);
  ASSERT_TRUE(in) << "missing " << MAGLEAD_ANALYSIS_DOC;
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string doc = ss.str();
  const std::string begin = "<!-- analysis-rules -->\n", end = "<!-- /analysis-rules -->";
  const auto a = doc.find(begin);
  const auto b = doc.find(end);
  ASSERT_NE(a, std::string::npos) << "docs/analysis.md has no " << begin;
  ASSERT_NE(b, std::string::npos) << "docs/analysis.md has no " << end;
  ASSERT_LT(a, b);
  EXPECT_TRUE(doc.substr(a + begin.size(), b - a - begin.size()) == rules::rules_markdown())
      << "docs/analysis.md's rule table is stale: put `maglead analysis-rules` between " << begin
      << "and " << end;
}
