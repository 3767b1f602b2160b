#pragma once
// The analysis is one pipeline (analyze_recording, analysis.cpp) over this small interface: a
// path is how one kind of system is analysed (the magnetic actuator, a force-driven axis, linear
// or rotary). The driver calls its stages in order; each stage does only what that path needs
// for it, and every path runs the one selection (selection.hpp) and builds its findings with the
// one conclusion (conclude).
#include <memory>
#include <sstream>
#include <string>

#include "maglead/analysis/analysis.hpp"

namespace maglead::analysis {

/// `value` as a stream writes it at `digits` significant digits: the paths' numbers in words.
inline std::string number_text(double value, int digits) {
  std::ostringstream o;
  o.precision(digits);
  o << value;
  return o.str();
}

class AnalysisPath {
 public:
  virtual ~AnalysisPath() = default;
  /// The recording's filtered signals, the samples the fit uses and what the recording resolves.
  virtual void prepare() = 0;
  /// The forward selection over the prepared samples with the path's rules, its final fit, and
  /// what the path names beside it (the actuator: from its stuck episodes).
  virtual void select() = 0;
  /// The findings, every field of them but what a check of the corrected model says (below),
  /// concluded once (conclude).
  virtual Findings findings() = 0;
  /// Where the model and the recording part: figures, the localisation in words, the fit over
  /// time; the findings stay as they are.
  virtual void figures(AnalysisResult& r) = 0;
  /// The corrected model (`r.corrected`), and what a check of it finds (the actuator's twin
  /// check: `r.findings.twin_force_check` and a note on each term it leaves out).
  virtual void corrected_model(AnalysisResult& r) = 0;
};

/// The magnetic actuator's path (model system "actuator"): the nut's force balance on sliding
/// samples, break-away and events from its stuck episodes, the twin's force check.
std::unique_ptr<AnalysisPath> actuator_path(const Recording& rec, const ModelFile& baseline,
                                            const ForceCalibration& cal, const ActuatorParams& act,
                                            const AnalysisOptions& options);

/// A force-driven axis's path, linear or rotary (its effects::AxisKind, from the recording and
/// the model; throws saying what to fix when they disagree): the drive force predicted from the
/// measured motion.
std::unique_ptr<AnalysisPath> axis_path(const Recording& rec, const ModelFile& baseline,
                                        const AnalysisOptions& options);

}  // namespace maglead::analysis
