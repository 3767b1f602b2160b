#pragma once
// The output of `maglead analyze`: analysis.json for machines, the corrected model file, and
// index.html for people: the analysis part of `maglead report`'s page (interactive fit chart,
// the residual maps as embedded PNG, written beside it).
#include <string>

#include "maglead/analysis/analysis.hpp"

namespace maglead::report {

/// Writes analysis.json, model_corrected.toml, index.html and its PNG maps into out_dir.
/// Throws std::runtime_error when a file cannot be written.
void write_analysis_outputs(const analysis::AnalysisResult& result, const std::string& out_dir);

}  // namespace maglead::report
