#pragma once
// The anomaly inspection behind `maglead report`: a recording replayed through the controller's
// TwinMonitor (twin::replay_monitor), compared with the load cell where one was logged, with
// step-outs, drift windows and where in time and space the twin and the machine part.
// Typed results only; report/ renders them.
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "maglead/analysis/figures.hpp"
#include "maglead/recording/recording.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead::analysis {

/// The signals over time, one value per recorded sample; NaN where not logged or not defined.
struct AnomalyTrace {
  std::vector<double> t_s, nut_pos_m, pos_set_m, phase_rad;
  std::vector<double> output_force_n;  // the load cell as output force (−load_force_n)
  std::vector<double> force_set_n;     // the controller's output-force setpoint
  std::vector<double>
      static_estimate_n;                // paper eq. 6 (logged, else recomputed); NaN off the branch
  std::vector<double> twin_estimate_n;  // the twin's dynamic observer
  std::vector<double> residual_pos_m;   // measured − twin-predicted nut position
  std::vector<double> drift_statistic;  // |g − g_ref| / margin: 1 sustained raises the warning
};

struct StepOut {
  double t_s = 0;
  int leads = 0;
  double nut_pos_m = 0;
  std::string seen_by;  // "twin replay" or "controller" (its logged counter)
};

struct TimeWindow {
  double start_s = 0, end_s = 0;
};

struct ErrorStats {
  double mean_abs_n = 0, rms_n = 0, max_abs_n = 0;
  std::size_t samples = 0;
};

struct Anomaly {
  AnomalyTrace trace;
  // The first samples hold the start-up transient (the servo pulling the screw onto the nut's
  // phase, the observer starting from zero load), not the machine's behaviour: statistics and
  // plots begin at this sample.
  std::size_t first_settled = 0;
  double settle_s = 0;
  std::vector<StepOut> step_outs;
  std::vector<TimeWindow> drift_windows, step_out_warnings;
  double max_drift_statistic = 0;
  int drift_observability = 0;  // twin::DriftObservability at the end of the replay
  // When the drift flag first judged (its reference formed, the stretches' scatter known) [s];
  // NaN: never.
  double drift_judged_from_s = std::numeric_limits<double>::quiet_NaN();
  bool has_load_cell = false, static_estimate_logged = false;
  std::optional<ErrorStats> static_error, twin_error;  // against the load cell
  // The static estimate (paper eq. 6) reads the coupling, which also carries friction up to the
  // model's break-away while the nut sticks: an error within this is friction, not an anomaly.
  double static_friction_band_n = 0;
  // Why the load cell is not compared although logged (its unit is wrong), else empty.
  std::string load_cell_unusable;
  std::optional<double> load_cell_constant_n;  // set aside because it reads this throughout
  std::size_t off_branch_samples = 0;
  double residual_pos_rms_m = 0, linear_count_m = 0;
  double sample_rate_hz = 0, duration_s = 0;
  Grid map_position_velocity;  // twin force error (or position residual) over velocity × position
};

/// Throws RecordingError for missing columns, std::invalid_argument for unusable data.
Anomaly inspect_recording(const Recording& rec, const twin::TwinMonitorConfig& monitor);
/// A load cell found not to read the load in newtons (LoadCellUnitError's `why`) is not compared:
/// the force errors against it are dropped and the reason kept (with the value a constant one
/// reads, whose cause is its wiring, not its unit).
void set_aside_load_cell(Anomaly& anomaly, std::string why,
                         std::optional<double> constant_n = std::nullopt);

/// Why the recording's load_force_n cannot be the load in newtons (another unit, or the other
/// sign: LoadCellUnitError's what()), judged as analyze and report judge it (by the analysis's
/// first stage, against the calibrated coupling beside friction and inertia; empty cells held
/// over from the row before); nothing when it can be, or when the recording is too short (fewer
/// than rules::kMinRows rows), has a column without any value, or is too still to tell. For the
/// commands that score against the load cell without analysing (estimate, twin-check).
std::optional<LoadCellUnitError> load_cell_unusable(const Recording& rec,
                                                    const ForceCalibration& cal,
                                                    const ActuatorParams& act);

}  // namespace maglead::analysis
