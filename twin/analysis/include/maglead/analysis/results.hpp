#pragma once
// The analysis's typed results: what analysis.json holds, as data. Units are in the names
// (`_n` newton, `_m` metre, `_s` second, `_pct` percent, …), as in the JSON the report library
// writes from them (report/analysis_json.hpp). An absent std::optional is a key the JSON leaves
// out; the one exception is Evidence::heldout_gain_pct, which is always written (null: none).
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "maglead/effects/axis_kind.hpp"

namespace maglead::analysis {

/// One named parameter value; the unit is the name's suffix. A count is a whole number.
struct Parameter {
  std::string name;
  double value = 0.0;
  bool is_count = false;
};
using Parameters = std::vector<Parameter>;

/// The value of `name`, or `fallback` when the parameters do not hold it.
double parameter_value(const Parameters& p, const std::string& name, double fallback = 0.0);
/// Sets `name` to `value` (replacing a value already there).
void set_parameter(Parameters& p, const std::string& name, double value, bool is_count = false);

/// `name value ± error` at the digits the error allows: the error to one significant digit (two
/// when that digit is 1), the value to the same decimal place; `name value` (4 significant
/// digits) when there is no error (not fitted, or a value on a scanned grid).
std::string with_error(const std::string& name, double value, double standard_error);
/// The same without the name ("0.94 ± 0.01"); empty when there is no error.
std::string value_with_error(double value, double standard_error);
/// A calibration error's bound on parameter `name`, with the parameter's unit: "3.6 N·s/m".
/// Two significant digits: it is a worst case, not a measurement.
std::string calibration_bound_text(const std::string& name, double bound);
/// Every value with its error (`standard_errors` by name; missing: none), in the values' order:
/// "coulomb_n 20.56 ± 0.05 N, offset_n 0.008 ± 0.004 N".
std::string summary_text(const Parameters& values, const Parameters& standard_errors);
/// The standard errors of the values that have one (value_with_error): a value scanned on a grid
/// or held at the model's has a spread of rounding (1e-18) that the text calls "(no standard
/// error)"; its key is left out, as analysis.json's reader would otherwise take it for exact.
Parameters stated_errors(const Parameters& values, const Parameters& standard_errors);
/// Whether a final residual is a misfit rather than the recording's own noise (the one rule the
/// conclusion and the headline share).
bool misfit_remains(double final_rms_n, double noise_floor_n);

/// Why an effect was named: its held-out statistics (sliding fits) or its events.
struct Evidence {
  std::optional<double> heldout_gain_pct;        // reduction of the held-out mean square error [%]
  std::optional<double> t_stat;                  // consistency of that gain over the segments
  std::optional<std::string> segments_improved;  // "7/10", or "12 releases"
  std::optional<double> explained_rms_n;
  std::optional<double> worst_segment_pct;
  std::optional<double> noise_floor_n;
  std::optional<bool> plausible;
  std::optional<double> breakaway_excess_pos_n, breakaway_excess_neg_n, encoder_count_force_n;
  std::optional<std::size_t> events;  // event effects: how many
  // What a finding must exceed (RMS force it changes): what the recording resolves (one
  // encoder count's rounding and the load-cell noise after the filter) and the stated minimum.
  std::optional<double> resolution_floor_n, minimum_n;
  // Sliding samples where the effect's law is not zero; below 100 % (an end zone) the force it
  // changes is measured there: explained_rms_n / sqrt(share) is what the floors were set against.
  std::optional<double> acting_share_pct;
};

/// Another effect that reproduces a named effect's contribution (the data cannot tell them apart).
struct Alternative {
  std::string id;
  Parameters parameters;
  double explains_pct = 0.0;
  std::optional<bool> plausible;
};

/// A named effect of the library the baseline leaves out (or an event kind: step_out, …).
struct EffectFinding {
  std::string id;
  Parameters parameters;
  std::string where;  // in words
  Evidence evidence;
  // Its part in the final model [%]: the baseline's held-out mean square error lost without it.
  double improvement_pct = 0.0;
  std::optional<bool> identifiable;
  std::vector<Alternative> alternatives;  // none: written not at all
  std::string finding;                    // empty: not written
  std::string note;                       // empty: not written
  Parameters standard_errors;             // from the held-out segments; none: not written
  // The most a coupling error within the calibration's accuracy (Evidence::minimum_n) moves each
  // value, same units: a bias the whole recording shares, which standard_errors cannot see.
  // Sliding fits of the actuator and the break-away read at release; none: not written.
  Parameters calibration_errors;
  std::string summary;  // "gain 0.94 ± 0.01", at the digits the error allows
};

/// A missing force that only an effect outside its physical range would explain: reported as
/// such, never as a finding.
struct Unexplained {
  std::string id;  // the library effect whose law fits best (with implausible parameters)
  Parameters parameters;
  double heldout_gain_pct = 0.0, explained_rms_n = 0.0;
  std::string where, check, message;
};

/// The twin's own force estimate (TwinMonitor, as `estimate --estimator twin`) against the
/// load cell, with the baseline and the corrected model. Checking only: the live observer never
/// reads the load cell.
struct TwinForceCheck {
  bool available = false;
  std::string reason;  // when not available
  double baseline_mae_n = 0.0, corrected_mae_n = 0.0;
  double resolved_n = 0.0;  // a rise must exceed this force the recording resolves [N]
  std::vector<std::string> kept, dropped;  // terms of the corrected model
};

/// The best candidate the selection did not take.
struct Rejected {
  std::string id;
  double heldout_gain_pct = 0.0;
  double t_stat = 0.0;
  std::optional<double> worst_segment_pct;
  std::optional<double> explained_rms_n;
  std::optional<std::string> reason;
  std::optional<Parameters> parameters;
};
/// The reason of a law the recording cannot judge at all (effects::Effect::unjudged_at begins
/// its reason with it): named in the headline whatever else it says.
inline constexpr const char* kNotJudged = "not judged: ";
/// The reason of the candidate the selection stopped at (short of significance).
inline constexpr const char* kBelowSignificance =
    "best remaining candidate, below the significance threshold";
/// "a misfit of X N RMS remains (floor Y N) …": what no named effect explains, and, when the
/// candidate the selection stopped at (in `not_selected`) explains most of it held out, that
/// candidate with why it was not taken, so a near miss is not read as "nothing in the library".
/// `kind`: the axis the residual is of (a rotary axis's is a torque in N·m, in its words).
struct Findings;
std::string misfit_text(const Findings& f, const effects::AxisKind& kind = effects::linear_axis());
/// "noise floor 0.0992 N", or, when the noise is not measurable below the logging step, "noise
/// floor not measurable below the 0.5 N logging step: 0.144 N".
std::string noise_floor_text(const Findings& f, const effects::AxisKind& kind);

/// Held-out (and fitted) error after each step of the selection; the first is the baseline.
struct ValidationStep {
  std::string model;  // "baseline", "+ coulomb_friction", …
  double heldout_rms_n = 0.0;
  double heldout_relative_error_pct = 0.0;
  std::optional<double> fitted_rms_n;
  std::optional<double> fitted_relative_error_pct;
};

/// Something that happened at a time: step_out, external_disturbance, misfit_window.
struct Event {
  std::string type;
  double t_s = 0.0;
  std::optional<double> start_s;
  std::optional<int> leads;
  std::optional<double> duration_s;
  std::optional<double> force_n;
  std::optional<double> rms_n;
};

/// Error of a model's force prediction over the used samples.
struct FitErrors {
  double rms_n = 0.0;
  double relative_error_pct = 0.0;
  double full_rate_rms_n = 0.0;
  double full_rate_relative_error_pct = 0.0;
  std::optional<double> heldout_rms_n;
  std::optional<Parameters> fitted_parameters;  // the baseline's terms as fitted (axis)
  Parameters standard_errors;  // of the fitted parameters, from the held-out segments
  std::string summary;         // those at the digits the errors allow; empty: not written
};

/// How the analysis ran, in words and numbers.
struct Method {
  std::string domain;
  std::string filter;
  int decimation = 1;
  std::optional<double> identification_bandwidth_hz;
  int folds = 0;
  std::string selection;
  std::string moving_only;
};

/// Break-away test over the stuck episodes, one direction.
struct BreakawaySide {
  std::size_t episodes = 0;
  double median_excess_n = 0.0;
  double se_n = 0.0;
};
struct BreakawayTest {
  BreakawaySide pos, neg;
};

/// Short-horizon re-simulation of the baseline and corrected twins from measured states.
struct TwinSimulation {
  bool available = false;
  std::string reason;  // when not available
  std::string integrator;
  double horizon_s = 0.0;
  int windows = 0;
  double baseline_rms_position_error_m = 0.0;
  double corrected_rms_position_error_m = 0.0;
  int baseline_failures = 0;
  int corrected_failures = 0;
  long steps = 0;
  long root_events = 0;
};

/// Everything analysis.json reports.
/// The smallest change of an effect's parameter the recording could name (actuator): the change
/// whose own force beside the model's terms, as an RMS over the samples the fit used, reaches
/// what the selection requires of a finding (the recording's floor and the stated minimum, the
/// larger). Smaller changes it cannot name: a model with nothing missing is right only to these
/// sizes (a change at the size may still fall short of the significance the selection asks).
struct Resolvable {
  std::string id, parameter, unit;
  double smallest_change = 0.0;
};
/// "nut_mass_kg 0.9 kg, viscous_n_s_per_m 1.2 N·s/m": each at 2 significant digits.
std::string resolvable_text(const std::vector<Resolvable>& r);
/// A parameter's unit from its name (the spec's names carry their unit): "N·s/m" for
/// `viscous_n_s_per_m`; empty when the name carries none.
std::string unit_of_parameter(const std::string& name);

struct Findings {
  std::string system;
  std::string recording;
  std::size_t samples = 0;
  std::size_t samples_used = 0;
  Method method;
  double noise_floor_n = 0.0;
  // The force's logging step when the noise is not measurable below it (noise_floor_n is then
  // the step's rounding error); 0 when not measurable and no step is found; none when measured.
  std::optional<double> noise_step_n;
  FitErrors baseline;
  FitErrors final_fit;
  std::vector<EffectFinding> effects;
  std::optional<bool> nothing_missing;
  std::string conclusion;
  std::vector<Rejected> not_selected;
  std::vector<ValidationStep> validation;
  std::vector<Event> events;
  std::optional<BreakawayTest> breakaway_test;
  std::optional<std::size_t> reversals;
  std::optional<std::size_t> input_edges;
  std::optional<TwinSimulation> twin_simulation;
  std::optional<Unexplained> unexplained;
  std::optional<TwinForceCheck> twin_force_check;
  std::string sliding_note;            // a recording that barely slides says so; empty: not written
  std::vector<Resolvable> resolvable;  // actuator: the smallest change it would have named
};

/// What a conclusion is built from besides the findings.
struct Concluding {
  std::size_t terms_named = 0;  // model terms the selection named (events are in the findings)
  bool implausible = false;     // a missing force no library effect explains plausibly
  std::string unresolved;       // appended to "no effect explains …" (the actuator's resolvable)
  std::string check;            // what a user should look at when a misfit remains
  const effects::AxisKind* kind = &effects::linear_axis();  // the axis the residual is of
};

/// The findings' one-line conclusion, built once: terms (and events) found; a missing force no
/// library effect explains plausibly; events found; a misfit (misfit_remains) with what to check,
/// and then nothing_missing is false — nothing named is not nothing missing; or nothing missing.
void conclude(Findings& f, const Concluding& c);

}  // namespace maglead::analysis
