#pragma once
// The output of `maglead analyze`: analysis.json for machines, report.html (figures embedded)
// for people, the figures as PNG and the corrected model file.
#include <string>

#include "maglead/analysis/analysis.hpp"

namespace maglead::report {

/// Writes analysis.json, report.html, the figures and model_corrected.toml into out_dir.
/// Throws std::runtime_error when a file cannot be written.
void write_analysis_outputs(const analysis::AnalysisResult& result, const std::string& out_dir);

}  // namespace maglead::report
