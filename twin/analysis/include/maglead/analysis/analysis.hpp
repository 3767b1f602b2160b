#pragma once
// Twin versus recording (issue 5): compare a baseline model with a recording in the force
// domain, locate the misfit, explain it by forward selection of named physical effects on
// held-out time segments, refit; the result (figures as data, the corrected model) is rendered
// by the report library (report/).
#include <functional>
#include <string>
#include <vector>

#include "maglead/analysis/figures.hpp"
#include "maglead/analysis/model_file.hpp"
#include "maglead/analysis/results.hpp"
#include "maglead/analysis/rules.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/recording/recording.hpp"

namespace maglead::analysis {

/// What only the actuator's path reads (analyze_recording with a model of system "actuator").
struct ActuatorPathOptions {
  // How well the calibration is known [N]; a finding must change the force by more
  // (0: not stated: a thousandth of the calibrated peak force, at least 0.07 N).
  double calibration_accuracy_n = 0.0;
  // Run the twin's force estimate with the corrected model against the load cell and keep only
  // terms that do not raise its error (several twin runs over the recording).
  bool twin_force_check = true;
};

/// What only the axis's path reads (a linear or rotary axis's model).
struct AxisPathOptions {
  int decimation = 0;                    // 0: down to the identification bandwidth, 1: none
  int max_terms = rules::kAxisMaxTerms;  // the actuator's is the rule max_terms, not an option
};

/// What both paths read, and each path's own options.
struct AnalysisOptions {
  // The defaults are the rule table's (maglead/analysis/rules.hpp), which says why.
  int folds = rules::kFolds;  // contiguous held-out time segments
  double filter_hz = 0.0;     // zero-phase low-pass of position (0: 100 Hz axis, 20 Hz actuator)
  double min_gain_pct =
      rules::kMinHeldOutGainPct;  // a term must cut the held-out error this much …
  double min_t = rules::kMinT;    // … consistently over the segments (t statistic of the gains)
  std::function<void(const std::string& stage, double fraction)> progress;
  ActuatorPathOptions actuator;
  AxisPathOptions axis;
};

struct AnalysisResult {
  Findings findings;  // what analysis.json reports (report::analysis_json writes it)
  ModelFile corrected;
  std::vector<Figure> figures;
  std::vector<std::string> where;  // localisation findings in words (analysis.json's "where")
  // The fit before and after over time: the force the model leaves out, baseline and corrected
  // (actuator recordings; no curves otherwise). NaN separates stretches of sliding samples.
  Chart fit_over_time;
  // The first line a user reads (headline_of): the findings with the model's values, what is
  // left unexplained, or why nothing could be judged.
  std::string headline;
};

/// Runs the whole analysis (the one entry; what it reads and refuses of a recording, for the
/// readers and `inspect`: maglead/analysis/reading.hpp; its first line: headline.hpp). `cal` is the
/// coupling calibration (actuator only). Throws RecordingError for missing columns and
/// std::invalid_argument for unusable data.
AnalysisResult analyze_recording(const Recording& rec, const ModelFile& baseline,
                                 const ForceCalibration& cal, const ActuatorParams& act,
                                 const AnalysisOptions& options);

}  // namespace maglead::analysis
