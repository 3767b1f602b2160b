#pragma once
// The twin's force estimate against the load cell (see actuator_twin_force.cpp).
#include <cstddef>
#include <optional>
#include <vector>

#include "maglead/analysis/model_file.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/recording/recording.hpp"

namespace maglead::analysis::actuator {

/// Most samples the twin check scores per model. The twin costs about 8 µs a sample without its
/// look-ahead, so one model's check stays near half a second however long the recording; the
/// models are compared on the same samples, so a difference the size of a finding shows well
/// within this many.
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

/// Mean absolute error of the twin's output-force estimate against the load cell over the
/// scoring windows [N]; nullopt when the twin is not built or the recording has no time span.
std::optional<double> twin_force_mae_n(const Recording& rec, const ActuatorParams& act,
                                       const ForceCalibration& cal, const ModelFile& model);

}  // namespace maglead::analysis::actuator
