#pragma once
// The analysis's part of a report page, one rendering for both pages that show it: `report`'s
// anomaly page (index.html) and `analyze`'s page (index.html). A user reads the same sections,
// tables and interactive fit chart in both.
#include <string>

#include "maglead/effects/axis_kind.hpp"
#include "maglead/report/anomaly_page.hpp"

namespace maglead::report {

/// The axis kind whose words and units the findings are shown in (a rotary axis's torques in
/// N·m, its laws in θ and τ); the actuator's are a linear axis's.
const effects::AxisKind& axis_words(const analysis::Findings& F);

/// The style of the conclusion's box: "ok" (green) only when the analysis judged nothing missing
/// (its conclusion "nothing is missing", nothing named, nothing_missing not false);
/// "unjudged" for a conclusion not judged; "bad" (attention) for anything found and for a misfit
/// or a force left unexplained, though no effect is named.
const char* conclusion_class(const analysis::Findings& F);

/// <head> content both pages share: charset, viewport, title, style and dygraphs.
std::string page_head(const std::string& title);

/// "N. What physics is missing": the effects with law, parameters, where and evidence, and where
/// the model misfits in words. `number` is the section's number on its page.
std::string physics_section(const AnalysisOutcome& o, int number);

/// The fit before and after: errors (in-sample and held-out) and the interactive fit chart.
std::string fit_part(const AnalysisOutcome& o);

/// Force pulses the analysis found, as a table (empty when none).
std::string analysis_events(const AnalysisOutcome& o);

/// The analysis's other figures (maps of the residual), as PNG embedded in the page.
std::string analysis_figures(const AnalysisOutcome& o);

}  // namespace maglead::report
