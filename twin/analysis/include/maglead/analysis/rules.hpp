#pragma once
// The analysis's decision rules in one table (issue 43): every threshold a decision compares
// against, with its unit, why it has this value and the ctest test that pins it. Decision code
// uses the named constants below, each read from the table by name, so the two cannot differ.
// docs/analysis.md's "How it decides" table is `maglead analysis-rules` (rules_markdown()).
#include <array>
#include <cstddef>
#include <string>
#include <string_view>

namespace maglead::analysis::rules {

struct Rule {
  std::string_view name;
  double value;
  std::string_view unit;   // "1" for a plain number or share
  std::string_view why;    // one line
  std::string_view test;   // a ctest test that fails when the rule is lost
  std::string_view stage;  // one of kStages
};

/// The order the analysis applies its stages in (the table is in this order too).
inline constexpr std::array<std::string_view, 7> kStages = {
    "prepare", "select", "break-away", "events", "refit", "twin check", "conclusion"};

// clang-format off
inline constexpr std::array kTable = {
    // prepare
    Rule{"filter_hz", 20.0, "Hz",
         "zero-phase low-pass of every signal: keeps the effects (below a few tens of Hz), averages encoder steps and load-cell noise",
         "GeneratedSuite.ViscousFriction", "prepare"},
    Rule{"filter_max_of_rate", 0.2, "1",
         "the filter's corner is at most this share of the logger's rate, so a slow logger still resolves it",
         "GeneratedSuite.ControlPositionMovesNamesNothing", "prepare"},
    Rule{"samples_per_filter_period", 5.0, "1",
         "sliding samples are kept this many per filter period: closer ones add work, not information",
         "GeneratedSuite.MassErrorOfAOneKilogramPayload", "prepare"},
    Rule{"min_rows", 200.0, "samples",
         "a recording shorter than this cannot fill ten held-out segments and the filter's edges",
         "RequireAnalysable.RefusesShortRecordsMissingColumnsAndNonNumbers", "prepare"},
    Rule{"held_count_counts", 0.5, "counts",
         "the raw count is held while it stays within half a count of where it stood",
         "StickSlip.ARecordingThatBarelySlidesSaysSo", "prepare"},
    Rule{"hidden_stop_counts", 2.0, "counts",
         "a count held while the filtered speed would cross this many counts is a stop the filter hides (stick-slip)",
         "GeneratedSuite.StribeckFrictionInMovesWithStops", "prepare"},
    Rule{"step_out_before_s", 0.1, "s",
         "samples this long before a step-out's start are not sliding: the phase is already leaving its branch",
         "GeneratedSuite.StepOutIsAnEventWithItsTime", "prepare"},
    Rule{"step_out_after_s", 0.3, "s",
         "samples this long after a step-out are not sliding, nor releases: the nut settles on its new lead",
         "GeneratedSuite.StepOutIsAnEventWithItsTime", "prepare"},
    Rule{"min_folds", 4.0, "segments",
         "fewer held-out segments give no t statistic worth the name",
         "GeneratedSuite.ControlHandPushNamesNothing", "prepare"},
    Rule{"folds", 10.0, "segments",
         "contiguous held-out time segments: enough for a t statistic, each long enough to hold moves",
         "GeneratedSuite.ControlHandPushNamesNothing", "prepare"},
    Rule{"min_sliding_samples", 50.0, "samples",
         "with fewer sliding samples (after decimation) the sliding fit is not judged: too little sliding",
         "StickSlip.ARecordingThatBarelySlidesSaysSo", "prepare"},
    Rule{"axis_filter_hz", 100.0, "Hz",
         "linear axis: zero-phase low-pass of position, above a drive's dynamics and below encoder noise",
         "Axis.GeneratedSpringIsNamedWithTheUnitsParameters", "prepare"},
    Rule{"axis_min_rate_hz", 50.0, "Hz",
         "axis: a logger's rate at least this, so a move's acceleration (M·a) is resolved; t_s written in milliseconds reads as 1 Hz",
         "Rotary.ASlowLoggerIsAnalysedWithTheFilterBelowItsNyquist", "prepare"},
    Rule{"axis_bandwidth_energy_lost", 0.01, "1",
         "linear axis: the identification bandwidth is where the acceleration loses at most this share of its energy",
         "Emps.AModelCorrectedOnTheFirstHalfPredictsTheSecond", "prepare"},
    Rule{"axis_decimation_of_rate", 0.4, "1",
         "linear axis: decimate while the bandwidth stays below this share of the new rate (80 % of its Nyquist frequency)",
         "Emps.EveryParameterHasAStandardErrorAndItsDigits", "prepare"},
    Rule{"axis_min_segment_samples", 100.0, "samples",
         "linear axis: decimation leaves every held-out segment at least this many samples",
         "Axis.AHeavyCarriagesChangedMassIsNamedWithTheModelItWasGiven", "prepare"},
    Rule{"axis_min_folds", 3.0, "segments",
         "linear axis: fewest held-out segments",
         "Axis.GeneratedSpringIsNamedWithTheUnitsParameters", "prepare"},
    Rule{"axis_min_usable_samples", 100.0, "samples",
         "linear axis: with fewer usable samples the axis hardly moves and the recording is refused",
         "Axis.AForceOfTheWrongSignIsNotExplainedPlausibly", "prepare"},
    Rule{"axis_rest_counts", 2.0, "counts",
         "axis: a stretch whose position stays within this many encoder counts of its start is held (an encoder dithers by one), its friction unknown: not fitted",
         "Rotary.AShaftHeldBetweenMovesIsNoEvent", "prepare"},
    Rule{"axis_rest_filter_periods", 2.0, "periods",
         "axis: a hold counts from this many periods of the position filter, and as many either side of it are left out too (the filters spread its force)",
         "Rotary.AShaftHeldBetweenMovesIsNoEvent", "prepare"},
    Rule{"barely_slides_one_in", 20.0, "samples",
         "with fewer than one sample in this many sliding, the result says the nut barely slides",
         "StickSlip.ARecordingThatBarelySlidesSaysSo", "prepare"},
    // select
    Rule{"min_held_out_gain_pct", 1.0, "%",
         "a term must cut the held-out mean square error this much to be named",
         "Selection.ATermIsNamedFromAHeldOutGainOfOnePercent", "select"},
    Rule{"min_t", 3.0, "1",
         "… consistently: t statistic of the per-segment gains, about one chance in a hundred over ten segments",
         "MixedRecordings.APlayBelowACountOfThePhaseIsNotClaimed", "select"},
    Rule{"localized_gain_factor", 10.0, "1",
         "an effect that helps only the segments where it occurs is consistent when its gain is this many times the minimum …",
         "GeneratedSuite.GainDriftOverTime", "select"},
    Rule{"localized_worst_segment_pct", -1.0, "%",
         "… and no segment gets worse by more than this",
         "GeneratedSuite.GainDriftOverTime", "select"},
    Rule{"acting_share", 0.1, "1",
         "actuator: a segment counts only where the term's contribution carries this share of its error (or of the floor's)",
         "GeneratedSuite.LoadCellDelay", "select"},
    Rule{"parsimony", 0.99, "1",
         "actuator: a simpler term reaching this share of the best one's gain, nested in it, goes first",
         "Selection.ANestedSimplerTermGoesFirstFromNinetyNinePercentOfTheGain", "select"},
    Rule{"axis_parsimony", 0.5, "1",
         "linear axis: a simpler term reaching this share of the best one's gain, nested in it, goes first",
         "Axis.GeneratedSpringIsNamedWithTheUnitsParameters", "select"},
    Rule{"nested_r2", 0.98, "1",
         "a simpler trial lying this much inside a richer one's span is the same explanation, nested",
         "GeneratedSuite.OffsetOrDirectionDependentFriction", "select"},
    Rule{"alternative_r2", 0.95, "1",
         "another effect reproducing this share of a taken term's contribution is named beside it as an alternative",
         "GeneratedSuite.OffsetOrDirectionDependentFriction", "select"},
    Rule{"spanned_r2", 0.999, "1",
         "linear axis: a column the model already spans to this share adds nothing the data can tell",
         "Emps.DirectionDependentFrictionSpansTheCoulombAndOffsetTakenFirst", "select"},
    Rule{"max_terms", 6.0, "terms",
         "actuator: most terms the forward selection adds",
         "GeneratedSuite.StribeckFrictionAndViscousFrictionInMovesWithStops", "select"},
    Rule{"axis_max_terms", 8.0, "terms",
         "linear axis: most terms the forward selection adds",
         "Emps.DirectionDependentFrictionSpansTheCoulombAndOffsetTakenFirst", "select"},
    Rule{"min_effect_of_peak", 1e-3, "1",
         "unless stated, the minimum a finding must change is this share of the calibrated peak force …",
         "Actuators/Calibration.IsOffByAFewHundredthsOfANewton/Other", "select"},
    Rule{"bench_accuracy_n", 0.07, "N",
         "… and at least a bench calibration's absolute error: nobody acts on less",
         "Actuators/Calibration.IsOffByAFewHundredthsOfANewton/Other", "select"},
    Rule{"acting_law_share", 1e-9, "1",
         "a law acts where it exceeds this share of its largest value (an end zone's compact support)",
         "ThirdActuator.AnEndEffectIsMeasuredInItsZones", "select"},
    // break-away
    Rule{"min_hold_s", 0.02, "s",
         "a stand shorter than this (or four samples) is encoder chatter, not a stuck episode",
         "StickSlip.AnOffsetIsReadFromTheReleasesWhereTheNutBarelySlides", "break-away"},
    Rule{"min_hold_samples", 4.0, "samples",
         "a stand must span this many samples to be a stuck episode at a slow logger",
         "StickSlip.AnOffsetIsReadFromTheReleasesWhereTheNutBarelySlides", "break-away"},
    Rule{"release_move_counts", 2.5, "counts",
         "a release is a move of this many counts along one direction, not encoder chatter",
         "StickSlip.ItsStallsAreNotPulses", "break-away"},
    Rule{"release_window_s", 0.03, "s",
         "the move is looked for within this long after the stand (or before it: it was moving)",
         "StickSlip.ItsStallsAreNotPulses", "break-away"},
    Rule{"release_rate_window_s", 0.05, "s",
         "the driving force's rise before a release is fitted over this long",
         "GeneratedSuite.StribeckFrictionUnderForceSteps", "break-away"},
    Rule{"min_releases", 3.0, "releases",
         "a side's break-away is judged on at least this many releases (and the friction level a thrown nut falls short of on as many jumps)",
         "GeneratedSuite.WeakStribeckFrictionInMovesWithStops", "break-away"},
    Rule{"breakaway_sigmas", 3.0, "standard errors",
         "break-away above the sliding level by the first-count lag and this many standard errors in both directions is Stribeck friction",
         "Actuators/Matrix.NamesNoEffectThatIsNotThere/Paper", "break-away"},
    Rule{"release_phase_counts", 0.5, "counts",
         "a release's phase is known to half a count: its coupling force is no excess",
         "GeneratedSuite.WeakStribeckFrictionInMovesWithStops", "break-away"},
    Rule{"expected_lag_of_bound", 0.75, "1",
         "the first-count lag expected is at most this share of its bound",
         "GeneratedSuite.StribeckFrictionUnderHandPushes", "break-away"},
    Rule{"median_se_factor", 1.2533, "1",
         "the standard error of a median is √(π/2) σ/√n for a normal sample",
         "GeneratedSuite.StribeckFrictionInMovesWithStops", "break-away"},
    Rule{"stribeck_velocity_fit_share", 0.01, "1",
         "Stribeck velocities whose fit is within this share of the worst one's error of the best fit alike",
         "Uncertainty.ParametersCarryTheirStandardErrorAtItsDigits", "break-away"},
    // events
    Rule{"pulse_sigmas", 8.0, "robust σ",
         "a disturbance pulse stands this far out of the residual's own spread …",
         "Pulses.APulseIsAnEventFromEightRobustSigmas", "events"},
    Rule{"pulse_max_s", 1.0, "s",
         "… for at most this long (longer is a misfit, not a pulse) …",
         "GeneratedSuite.ExternalDisturbancePulsesAreEvents", "events"},
    Rule{"pulse_min_spacing_s", 2.0, "s",
         "… and pulses are at least this far apart on average: more often is a misfit",
         "GeneratedSuite.ExternalDisturbancePulsesAreEvents", "events"},
    Rule{"pulse_min_filter_periods", 0.5, "filter periods",
         "a run shorter than this is the ringing of a transition, not a force that acted",
         "StickSlip.ItsStallsAreNotPulses", "events"},
    Rule{"pulse_flank_filter_periods", 2.0, "filter periods",
         "a pulse's flanks (and the samples a law is fitted on away from it) reach this far",
         "Pulses.APulseALibraryLawExplainsIsNotADisturbance", "events"},
    Rule{"pulse_edge_filter_periods", 4.0, "filter periods",
         "the zero-phase filter's response dies out within this many filter periods: no pulse that near the recording's ends",
         "GeneratedSuite.ExternalDisturbancePulsesAreEvents", "events"},
    Rule{"pulse_opposite_factor", 2.0, "1",
         "one sign: the swing opposite the peak is at most this times the filter's own undershoot",
         "MixedRecordings.APulseThatStallsAMovingNutIsAnEvent", "events"},
    Rule{"pulse_gap_steps", 1.5, "sample steps",
         "a gap in time longer than this ends a run of the residual",
         "MixedRecordings.APulseThatStopsASlidingNutIsAnEvent", "events"},
    Rule{"pulse_min_samples", 100.0, "samples",
         "a residual shorter than this is not searched for pulses",
         "GeneratedSuite.ControlForceStepsNamesNothing", "events"},
    // refit
    Rule{"axis_drive_timing_samples", 0.5, "samples",
         "axis: a logged drive value may stand for the period after its time stamp (a held setpoint) or before it (an averaged current), which no recording states: each parameter's error adds its change over this offset either way, as a uniform uncertainty",
         "AxisCoverage.RotaryServosAndLinearAxesAreCoveredByTheirErrors", "refit"},
    // twin check
    Rule{"twin_check_blocks", 8.0, "blocks",
         "the scored samples are cut into this many blocks: a standard error from seven degrees of freedom",
         "analysis_twin_round_trip", "twin check"},
    Rule{"twin_rise_sigmas", 2.0, "standard errors",
         "a term leaves the corrected model when the twin's error rises by more than this (chance: one time in forty)",
         "analysis_twin_round_trip", "twin check"},
    // conclusion
    Rule{"where_min_bin_samples", 20.0, "samples",
         "linear axis: a residual map's bin is judged on at least this many samples …",
         "Axis.AForceOfTheWrongSignIsNotExplainedPlausibly", "conclusion"},
    Rule{"where_bin_of_rms", 0.5, "1",
         "… and stands out where its mean residual exceeds this share of the overall RMS …",
         "Axis.AForceOfTheWrongSignIsNotExplainedPlausibly", "conclusion"},
    Rule{"where_bin_sigmas", 4.0, "standard errors",
         "… and this many of its standard errors",
         "Axis.AForceOfTheWrongSignIsNotExplainedPlausibly", "conclusion"},
    Rule{"where_reversal_jump_of_rms", 0.3, "1",
         "linear axis: mean residuals by direction differing by this share of the RMS jump at velocity reversals",
         "Emps.DirectionDependentFrictionSpansTheCoulombAndOffsetTakenFirst", "conclusion"},
    Rule{"where_growth_factor", 1.5, "1",
         "linear axis: the residual grows when the last third's RMS is this many times the first's …",
         "Emps.AModelCorrectedOnTheFirstHalfPredictsTheSecond", "conclusion"},
    Rule{"where_growth_of_rms", 0.3, "1",
         "… and above this share of the overall RMS",
         "Emps.AModelCorrectedOnTheFirstHalfPredictsTheSecond", "conclusion"},
    Rule{"where_window_over_median", 3.0, "1",
         "linear axis: a time window whose RMS is this many times the median and the floor is a misfit window",
         "Axis.IsolatedForcePulsesAreEventsAtTheirTimes", "conclusion"},
    Rule{"where_edge_of_range", 0.05, "1",
         "linear axis: a setpoint step beyond this share of its range is an input edge the residual is averaged around",
         "Axis.IsolatedForcePulsesAreEventsAtTheirTimes", "conclusion"},
    Rule{"misfit_over_floor", 2.0, "1",
         "a final residual above this many times the floor is a misfit the model leaves out",
         "analysis_resolvable", "conclusion"},
    Rule{"most_of_it_pct", 50.0, "%",
         "a candidate short of significance taking this much of the held-out error is named as the misfit's likeliest account",
         "analysis_resolvable", "conclusion"},
    Rule{"one_way_other_share", 0.05, "1",
         "actuator: sliding samples the other way below this share make a recording of one direction of travel, where laws differing by the direction fit alike",
         "GeneratedSuite.AOneWayMoveWithLawsAlikeIsNotJudged", "conclusion"},
    Rule{"one_way_alike_alternatives", 3.0, "alternatives",
         "actuator: on one direction of travel, a finding with this many alternatives fitting alike names no law: the headline says not judged",
         "GeneratedSuite.AOneWayMoveWithLawsAlikeIsNotJudged", "conclusion"},
};
// clang-format on

/// The table's value of the rule `name`; a name not in the table does not compile.
consteval double value_of(std::string_view name) {
  for (const auto& r : kTable)
    if (r.name == name) return r.value;
  throw "no such rule";  // not a constant expression: a compile error
}

consteval bool names_unique() {
  for (std::size_t i = 0; i < kTable.size(); ++i)
    for (std::size_t j = i + 1; j < kTable.size(); ++j)
      if (kTable[i].name == kTable[j].name) return false;
  return true;
}
static_assert(names_unique(), "two rules share a name");

consteval bool stages_known_and_in_order() {
  std::size_t at = 0;
  for (const auto& r : kTable) {
    while (at < kStages.size() && kStages[at] != r.stage) ++at;
    if (at == kStages.size()) return false;
  }
  return true;
}
static_assert(stages_known_and_in_order(), "a rule's stage is unknown or out of order");

// clang-format off
inline constexpr double kFilterHz = value_of("filter_hz");
inline constexpr double kFilterMaxOfRate = value_of("filter_max_of_rate");
inline constexpr double kSamplesPerFilterPeriod = value_of("samples_per_filter_period");
inline constexpr std::size_t kMinRows = static_cast<std::size_t>(value_of("min_rows"));
inline constexpr double kHeldCountCounts = value_of("held_count_counts");
inline constexpr double kHiddenStopCounts = value_of("hidden_stop_counts");
inline constexpr double kStepOutBefore_s = value_of("step_out_before_s");
inline constexpr double kStepOutAfter_s = value_of("step_out_after_s");
inline constexpr int kMinFolds = static_cast<int>(value_of("min_folds"));
inline constexpr int kFolds = static_cast<int>(value_of("folds"));
inline constexpr std::size_t kMinSlidingSamples = static_cast<std::size_t>(value_of("min_sliding_samples"));
inline constexpr double kAxisFilterHz = value_of("axis_filter_hz");
inline constexpr double kAxisMinRateHz = value_of("axis_min_rate_hz");
inline constexpr double kAxisBandwidthEnergyLost = value_of("axis_bandwidth_energy_lost");
inline constexpr double kAxisDecimationOfRate = value_of("axis_decimation_of_rate");
inline constexpr std::size_t kAxisMinSegmentSamples = static_cast<std::size_t>(value_of("axis_min_segment_samples"));
inline constexpr int kAxisMinFolds = static_cast<int>(value_of("axis_min_folds"));
inline constexpr double kAxisMinUsableSamples = value_of("axis_min_usable_samples");
inline constexpr double kAxisRestCounts = value_of("axis_rest_counts");
inline constexpr double kAxisRestFilterPeriods = value_of("axis_rest_filter_periods");
inline constexpr std::size_t kBarelySlidesOneIn = static_cast<std::size_t>(value_of("barely_slides_one_in"));
inline constexpr double kMinHeldOutGainPct = value_of("min_held_out_gain_pct");
inline constexpr double kMinT = value_of("min_t");
inline constexpr double kLocalizedGainFactor = value_of("localized_gain_factor");
inline constexpr double kLocalizedWorstSegmentPct = value_of("localized_worst_segment_pct");
inline constexpr double kActingShare = value_of("acting_share");
inline constexpr double kParsimony = value_of("parsimony");
inline constexpr double kAxisParsimony = value_of("axis_parsimony");
inline constexpr double kNestedR2 = value_of("nested_r2");
inline constexpr double kAlternativeR2 = value_of("alternative_r2");
inline constexpr double kSpannedR2 = value_of("spanned_r2");
inline constexpr int kMaxTerms = static_cast<int>(value_of("max_terms"));
inline constexpr int kAxisMaxTerms = static_cast<int>(value_of("axis_max_terms"));
inline constexpr double kMinEffectOfPeak = value_of("min_effect_of_peak");
inline constexpr double kBenchAccuracyN = value_of("bench_accuracy_n");
inline constexpr double kActingLawShare = value_of("acting_law_share");
inline constexpr double kMinHold_s = value_of("min_hold_s");
inline constexpr double kMinHoldSamples = value_of("min_hold_samples");
inline constexpr double kReleaseMoveCounts = value_of("release_move_counts");
inline constexpr double kReleaseWindow_s = value_of("release_window_s");
inline constexpr double kReleaseRateWindow_s = value_of("release_rate_window_s");
inline constexpr std::size_t kMinReleases = static_cast<std::size_t>(value_of("min_releases"));
inline constexpr double kBreakawaySigmas = value_of("breakaway_sigmas");
inline constexpr double kReleasePhaseCounts = value_of("release_phase_counts");
inline constexpr double kExpectedLagOfBound = value_of("expected_lag_of_bound");
inline constexpr double kMedianSeFactor = value_of("median_se_factor");
inline constexpr double kStribeckVelocityFitShare = value_of("stribeck_velocity_fit_share");
inline constexpr double kPulseSigmas = value_of("pulse_sigmas");
inline constexpr double kPulseMax_s = value_of("pulse_max_s");
inline constexpr double kPulseMinSpacing_s = value_of("pulse_min_spacing_s");
inline constexpr double kPulseMinFilterPeriods = value_of("pulse_min_filter_periods");
inline constexpr double kPulseFlankFilterPeriods = value_of("pulse_flank_filter_periods");
inline constexpr double kPulseEdgeFilterPeriods = value_of("pulse_edge_filter_periods");
inline constexpr double kPulseOppositeFactor = value_of("pulse_opposite_factor");
inline constexpr double kPulseGapSteps = value_of("pulse_gap_steps");
inline constexpr std::size_t kPulseMinSamples = static_cast<std::size_t>(value_of("pulse_min_samples"));
inline constexpr double kAxisDriveTimingSamples = value_of("axis_drive_timing_samples");
inline constexpr std::size_t kTwinCheckBlocks = static_cast<std::size_t>(value_of("twin_check_blocks"));
inline constexpr double kTwinRiseSigmas = value_of("twin_rise_sigmas");
inline constexpr double kWhereMinBinSamples = value_of("where_min_bin_samples");
inline constexpr double kWhereBinOfRms = value_of("where_bin_of_rms");
inline constexpr double kWhereBinSigmas = value_of("where_bin_sigmas");
inline constexpr double kWhereReversalJumpOfRms = value_of("where_reversal_jump_of_rms");
inline constexpr double kWhereGrowthFactor = value_of("where_growth_factor");
inline constexpr double kWhereGrowthOfRms = value_of("where_growth_of_rms");
inline constexpr double kWhereWindowOverMedian = value_of("where_window_over_median");
inline constexpr double kWhereEdgeOfRange = value_of("where_edge_of_range");
inline constexpr double kMisfitOverFloor = value_of("misfit_over_floor");
inline constexpr double kMostOfItPct = value_of("most_of_it_pct");
inline constexpr double kOneWayOtherShare = value_of("one_way_other_share");
inline constexpr std::size_t kOneWayAlikeAlternatives = static_cast<std::size_t>(value_of("one_way_alike_alternatives"));
// clang-format on

/// The table as Markdown, one row per rule in stage order (docs/analysis.md's "How it decides"
/// block is this text).
std::string rules_markdown();

/// The tests the table names, one per line, sorted, each once.
std::string rules_tests();

}  // namespace maglead::analysis::rules
