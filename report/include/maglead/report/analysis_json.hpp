#pragma once
// analysis.json: the analysis's typed results (maglead/analysis/results.hpp) as JSON, for
// machines. Keys are sorted (nlohmann::json's objects); absent optionals are absent keys.
#include <nlohmann/json.hpp>

#include "maglead/analysis/analysis.hpp"

namespace maglead::report {

/// The content of analysis.json.
nlohmann::json analysis_json(const analysis::AnalysisResult& result);

/// Named parameter values as one JSON object (counts as whole numbers).
nlohmann::json parameters_json(const analysis::Parameters& parameters);

}  // namespace maglead::report
