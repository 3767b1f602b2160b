#pragma once
// Stages of the actuator analysis with typed results (see actuator_analysis.cpp).
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "maglead/analysis/results.hpp"
#include "maglead/analysis/rules.hpp"
#include "maglead/effects/effect.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/recording/recording.hpp"
#include "pulses.hpp"
#include "selection.hpp"

namespace maglead::analysis::actuator {

/// The screw angle: the logged column itself (not copied), or the motor angle through the gear
/// (the header's gear_ratio wins) computed into `geared`, which must outlive the result.
const std::vector<double>& angle_column(const Recording& rec, const ActuatorParams& act,
                                        std::vector<double>& geared);

using analysis::BaselineTerm;

/// The model the recording is compared with: nominal dynamics plus the terms it already has.
struct Baseline {
  double nut_mass_kg = 0.12, viscous_n_s_per_m = 2.0, coulomb_n = 7.5;
  std::vector<BaselineTerm> terms;
};

/// What the actuator's stages read: the rules' values, the user's options (AnalysisOptions and
/// ActuatorPathOptions) and the effects not offered.
struct StageOptions {
  // The defaults are the rule table's (maglead/analysis/rules.hpp), which says why.
  int folds = rules::kFolds;            // contiguous held-out time segments
  double filter_hz = rules::kFilterHz;  // zero-phase low-pass of every signal
  double min_gain_pct =
      rules::kMinHeldOutGainPct;  // held-out mean-square error a term must remove …
  double min_t = rules::kMinT;    // … consistently over the segments (t of per-segment gains)
  double acting_share = rules::kActingShare;  // segments where the term carries this share count
  // … and change the force by more than the recording resolves (ActuatorPrepared::floor_n) and than
  // a stated minimum: how well the calibration is known. Unless the user states it, a bench
  // calibration's: a thousandth of its range, and not better than a bench's absolute error (a
  // load cell and a fixture: the bench calibrations are off by up to 0.07 N, our own
  // `calibrate` on a bench with an unseen 0.05 N force by 0.070 N); below that nobody can act.
  double min_effect_of_peak = rules::kMinEffectOfPeak;
  double bench_accuracy_n = rules::kBenchAccuracyN;
  double calibration_accuracy_n = 0;     // stated by the user: the minimum instead (0: not stated)
  double parsimony = rules::kParsimony;  // a simpler term reaching this share of the best gain wins
  double breakaway_sigmas = rules::kBreakawaySigmas;  // break-away excess significance
  int max_terms = rules::kMaxTerms;
  double pulse_sigmas = rules::kPulseSigmas;  // a disturbance pulse stands this far out …
  double pulse_max_s = rules::kPulseMax_s;    // … for at most this long …
  double pulse_min_spacing_s = rules::kPulseMinSpacing_s;  // … and this far apart on average
  std::vector<std::string> exclude;                        // ids already in the baseline model
};

struct SlipEvent {
  double t_s;      // the phase passed ±π: the nut is mid-slip
  double start_s;  // it last sat inside the stable branch (|φ| ≤ π/2)
  int leads;
};

struct StuckEpisode {
  double t_release_s = 0, dir = 0, net_n = 0;  // net driving force on the nut at release
  double net_rate_n_s = 0;  // how fast that force rose while the nut was held (along dir)
  double held_s = 0;        // how long the count stood still
  bool interrupts = false;  // the nut was moving along dir when it stopped (a stall, not a start)
  effects::State state;
  // The net driving force that three quarters of the stand held (along dir) and its sample: what
  // friction held for most of it, not a transient at its start.
  double held_net_n = 0;
  effects::State held;
};

/// A jump: the nut left one stand and reached the next (within a pulse's longest), and the work
/// the recorded forces did on it over its travel.
struct Jump {
  double t_s = 0, duration_s = 0;  // when it left its stand (since t0) and how long it moved
  double dir = 0;                  // its first move's direction
  double work_j = 0;  // Σ net drive (coupling, load, the baseline's terms) × Δp over raw samples
  double path_m = 0;  // Σ |Δp|: the travel, back and forth
  effects::State from, to;  // the stands it left and reached (held states)
  bool slides = false;      // it left a sliding sample: the residual sees what moved the nut
};

/// Per recording sample, its locked-count run (−1: none), and per run its period in samples.
struct LockedRuns {
  std::vector<int> run, period;
};

/// The sliding samples (decimated), one entry per sample in each column; moved together.
struct SampleColumns {
  std::vector<effects::State> states;
  std::vector<double> residual;        // the baseline's missing force at those samples [N]
  std::vector<int> locked_run;         // the locked-count run each lies in (−1: none)
  std::vector<unsigned char> ringing;  // 1: the nut rings so that it stops or reverses (no fit)
  void resize(std::size_t n) {
    states.resize(n), residual.resize(n), locked_run.resize(n), ringing.resize(n);
  }
  void set(std::size_t i, const SampleColumns& from, std::size_t j) {
    states[i] = from.states[j], residual[i] = from.residual[j];
    locked_run[i] = from.locked_run[j], ringing[i] = from.ringing[j];
  }
  void push(const SampleColumns& from, std::size_t j) {
    states.push_back(from.states[j]), residual.push_back(from.residual[j]);
    locked_run.push_back(from.locked_run[j]), ringing.push_back(from.ringing[j]);
  }
};

/// The actuator's recording prepared: its sliding samples, floors, stuck episodes and jumps.
struct ActuatorPrepared : SampleColumns {
  double fs_hz = 0, filter_hz = 0, lead_m = 0, count_m = 0, v_min_m_s = 0, t0_s = 0;
  double duration_s = 0, load_noise_n = 0;
  std::optional<double> load_noise_step_n;  // the logging step the noise rests on (not measured)
  double load_filtered_noise_n = 0, load_rate_noise_n_s = 0;  // that noise after the filter
  double count_force_n = 0;  // coupling force of one linear encoder count at φ = 0
  double floor_n = 0;        // RMS force the recording resolves: one count's rounding and the
                             // load-cell noise, both after the filter
  double minimum_n =
      0;  // the stated minimum (the calibration accuracy, else a thousandth of the peak)
  effects::Scales scales;     // the calibrated peak force, the fastest sliding speed: the
                              // effect units' plausible ranges are stated in these
  double locked_share = 0;    // sliding samples whose count rate is locked to the sample clock
  double locked_floor_n = 0;  // floor_n with what a locked count's rounding may hold there
  int decimation = 1;
  std::size_t samples = 0;
  std::vector<int> locked_period;  // per run, the samples its count pattern repeats after
  std::vector<SlipEvent> slips;
  std::vector<StuckEpisode> stuck;
  std::vector<Jump> jumps;
  struct Window {
    double from_s, to_s;  // since t0_s
  };
  std::vector<Window> stops;  // stops the filtered speed hides, widened by the filter's support
};

/// The selection's result (the one type both paths read) with what the actuator adds: the
/// errors over the sliding samples and the corrected residual.
struct SlidingSelection : selection::Result {
  double baseline_sse = 0, final_sse = 0, measured_ss = 0;
  std::vector<double> final_residual;  // at ActuatorPrepared::states, after every chosen term
  std::size_t samples_used = 0;
  bool too_little_sliding = false;
  std::vector<Resolvable> resolvable;  // beside the final model's terms
};

/// The break-away read from the releases, per direction (analysis.json's breakaway_test holds
/// its episodes, median excess and standard error).
struct Breakaway {
  struct Side {
    std::size_t episodes = 0;
    double median_excess_n = 0, se_n = 0;
    double count_force_n = 0;   // coupling force of one encoder count at release (resolution)
    double lag_bound_n = 0;     // most the force rises before a Coulomb nut moves one count
    double lag_expected_n = 0;  // what it rises behind a break-away of the median excess
  } pos, neg;
};

/// The load cell's unit and sign against the calibrated coupling beside friction and inertia
/// (the first thing prepare_actuator judges): throws LoadCellUnitError when it cannot be the load
/// in newtons. Its columns must have a value in every row.
void judge_load_cell(const Recording& rec, const ForceCalibration& cal, const ActuatorParams& act);

ActuatorPrepared prepare_actuator(const Recording& rec, const Baseline& base,
                                  const ForceCalibration& cal, const ActuatorParams& act,
                                  const StageOptions& opt);
/// The sliding samples a hidden stop reaches (ActuatorPrepared::stops), set aside with their
/// places.
struct StopSamples : SampleColumns {
  std::vector<std::size_t> at;  // their indices in the whole sample set, increasing
};
/// Takes those samples out of `P` (its locked floor follows): the stages see the recording
/// without them, and no second copy of the sample set is made.
StopSamples take_stops(ActuatorPrepared& P);
/// `P` as it was before take_stops (the samples back in their places, the floor recomputed).
void put_back(ActuatorPrepared& P, const StopSamples& aside);
/// The forward selection's rule in words (the report's method).
std::string selection_rule(const StageOptions& opt);
SlidingSelection select_sliding(const ActuatorPrepared& P, const StageOptions& opt,
                                const std::function<void(double)>& progress);
std::optional<selection::Found> stribeck_from_breakaway(const ActuatorPrepared& P,
                                                        const Baseline& base,
                                                        const SlidingSelection& sel,
                                                        const Breakaway& bt,
                                                        const StageOptions& opt);
/// Significance of a break-away above the kinetic level on one side: the median excess beyond the
/// first-count lag bound and half a count's force, in standard errors (−∞ below 3 releases).
double breakaway_margin(const Breakaway::Side& s);
/// Why a Stribeck term the sliding fit chose is not named: the recording has releases in both
/// directions and they show no break-away above the kinetic level beyond what the encoder
/// resolves. None: the term stands (or none was chosen, or the releases are too few to tell).
std::optional<std::string> stribeck_unseen_at_rest(const ActuatorPrepared& P, const Baseline& base,
                                                   const SlidingSelection& sel,
                                                   const StageOptions& opt);
/// Where the nut barely slides (no sliding fit), a force along +p the load cell does not see, from
/// the releases: it lowers the break-away read in +p and raises it in −p by as much. None: too
/// few releases, or a difference the releases do not resolve.
std::optional<selection::Found> offset_from_breakaway(const ActuatorPrepared& P,
                                                      const SlidingSelection& sel,
                                                      const Breakaway& bt, const StageOptions& opt);
std::vector<pulses::Pulse> actuator_pulses(const ActuatorPrepared& P, const SlidingSelection& sel,
                                           const StageOptions& opt);
Breakaway breakaway_test(const ActuatorPrepared& P, const Baseline& base,
                         const std::vector<selection::Found>& chosen);

}  // namespace maglead::analysis::actuator
