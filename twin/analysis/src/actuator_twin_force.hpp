#pragma once
// The twin's force estimate against the load cell (see actuator_twin_force.cpp).
#include <cstddef>
#include <optional>
#include <vector>

#include "maglead/analysis/model_file.hpp"
#include "maglead/analysis/rules.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/recording/recording.hpp"

namespace maglead::analysis::actuator {

/// Most samples the twin check scores per model. The check runs the twin's observer without the
/// open-loop twin, about 0.6 µs a sample, so one model's check stays near 40 ms however long the
/// recording; the models are compared on the same samples, so a difference the size of a finding
/// shows well within this many.
inline constexpr std::size_t kTwinCheckSamples = 65536;
/// Windows the check spreads over a recording longer than that (an hour's drift is sampled
/// from start to end, not only its first minute).
inline constexpr std::size_t kTwinCheckWindows = 8;

struct SampleWindow {
  std::size_t begin = 0, end = 0;  // [begin, end) sample indices
};
/// The whole recording when it has at most `budget` samples, else `windows` equal windows of
/// budget / windows samples, spread evenly from its start to its end.
std::vector<SampleWindow> scoring_windows(std::size_t samples, std::size_t budget,
                                          std::size_t windows);

/// Blocks the scored samples are cut into (in order) so two models' errors can be compared with
/// their own spread (the rule twin_check_blocks).
inline constexpr std::size_t kTwinCheckBlocks = rules::kTwinCheckBlocks;

/// The twin's output-force error against the load cell [N]: the mean absolute error over the
/// scoring windows, and the same per block of the scored samples (kTwinCheckBlocks of them).
struct TwinForceErrors {
  double mae_n = 0.0;
  std::vector<double> block_mae_n;
};
/// nullopt when the twin is not built or the recording has no time span.
std::optional<TwinForceErrors> twin_force_errors(const Recording& rec, const ActuatorParams& act,
                                                 const ForceCalibration& cal,
                                                 const ModelFile& model);
/// Whether `with` is worse than `without` beyond the noise of the difference: the paired rise
/// over the blocks is more than kRiseBeyondNoise standard errors and more than `resolved_n`, the
/// force the recording resolves (a rise below it is the estimator's own jitter, not the model's).
bool rises_beyond_noise(const TwinForceErrors& with, const TwinForceErrors& without,
                        double resolved_n);
/// The rule twin_rise_sigmas: a rise that chance alone exceeds about one time in forty.
inline constexpr double kRiseBeyondNoise = rules::kTwinRiseSigmas;

}  // namespace maglead::analysis::actuator
