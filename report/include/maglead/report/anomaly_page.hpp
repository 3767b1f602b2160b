#pragma once
// The anomaly report of `maglead report`: one self-contained HTML page (index.html) and
// report.json, rendered from the anomaly inspection and, where it ran, the analysis.
#include <optional>
#include <string>

#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/anomaly.hpp"

namespace maglead::report {

/// The analysis's part in the report: its result, or why there is none.
struct AnalysisOutcome {
  enum class Status { done, skipped, failed } status = Status::skipped;
  std::string reason;  // skipped or failed: why
  std::optional<analysis::AnalysisResult> result;
  bool load_cell_unusable = false;  // failed because load_force_n is not the load in newtons
  std::optional<double> load_cell_constant_n;  // … because it reads this value throughout
};

/// One line for the operator: "no anomaly found" or "attention: …".
std::string anomaly_headline(const analysis::Anomaly& anomaly, const AnalysisOutcome& analysis);

/// Writes OUT_DIR/index.html (dygraphs inlined, the map embedded), report.json and the map's
/// PNG. Throws std::runtime_error when a file cannot be written.
void write_anomaly_report(const std::string& out_dir, const std::string& recording,
                          const analysis::Anomaly& anomaly, const AnalysisOutcome& analysis);

}  // namespace maglead::report
