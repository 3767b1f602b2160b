#pragma once
// The analysis's first line (AnalysisResult::headline), from the findings and the baseline.
#include <string>

#include "maglead/analysis/model_file.hpp"
#include "maglead/analysis/results.hpp"

namespace maglead::analysis {

/// The findings in one line: "found: viscous friction viscous_n_s_per_m 22.55 ± 0.12 N·s/m
/// (model 2 N·s/m)", "not judged: too little sliding …", "a misfit of X N RMS remains …" or
/// "nothing missing: …"; never "nothing missing" for what was not judged.
std::string headline_of(const Findings& findings, const ModelFile& baseline);

}  // namespace maglead::analysis
