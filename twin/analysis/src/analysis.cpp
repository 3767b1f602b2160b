// analyze_recording: the one driver of the analysis, the same stages for every path (path.hpp).
#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/headline.hpp"

#include <stdexcept>

#include "path.hpp"

namespace maglead::analysis {

AnalysisResult analyze_recording(const Recording& rec, const ModelFile& model,
                                 const ForceCalibration& cal, const ActuatorParams& act,
                                 const AnalysisOptions& opt) {
  // A recording that states an axis kind is no actuator's: say which model it needs rather than
  // which actuator column it lacks.
  if (model.system == "actuator" && rec.meta("axis"))
    throw std::invalid_argument(rec.path +
                                ": the recording is an axis ('# axis: " + *rec.meta("axis") +
                                "') and the model the magnetic actuator's: give the axis's "
                                "baseline with --model (system = \"rotary\" or \"axis\")");
  const auto progress = [&](const std::string& stage, double f) {
    if (opt.progress) opt.progress(stage, f);
  };
  const std::unique_ptr<AnalysisPath> path = model.system == "actuator"
                                                 ? actuator_path(rec, model, cal, act, opt)
                                                 : axis_path(rec, model, opt);
  progress("prepare", 0.0);
  path->prepare();
  progress("prepare", 1.0);
  path->select();
  progress("selection", 1.0);
  AnalysisResult r;
  r.findings = path->findings();
  path->figures(r);
  path->corrected_model(r);
  r.headline = headline_of(r.findings, model);
  progress("done", 1.0);
  return r;
}

}  // namespace maglead::analysis
