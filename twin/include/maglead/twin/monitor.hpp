#pragma once
// TwinMonitor: the controller's digital twin, stepped once per control tick beside the loop.
// It knows nothing of Modbus; the controller copies TwinOutputs into its registers.
//
// Per tick: feed the measured screw angle and nut position (quantized encoders, SI units) and
// the force setpoint if force control is active (NaN otherwise). step() is noexcept, does not
// allocate and does not block; everything is created in the constructor / reset().
#include <limits>
#include <memory>
#include <string>

#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/physics/load_observer.hpp"
#include "maglead/physics/stick_filter.hpp"
#include "maglead/twin/hybrid_twin.hpp"
#include "maglead/twin/model.hpp"

namespace maglead::twin {

struct TwinInputs {
  double t_s = 0.0;               // loop time of this sample
  double screw_angle_rad = 0.0;   // measured θ (motor encoder / gear ratio), continuous
  double nut_pos_m = 0.0;         // measured p (linear encoder)
  double force_setpoint_n = 0.0;  // output-force setpoint F_out; NaN if not in force control
  double load_force_n = std::numeric_limits<double>::quiet_NaN();  // load cell (force on the nut
                                                                   // from the load, F_ext); NaN
                                                                   // without one. Only for the
                                                                   // check gain, never the flag
  bool free_move = false;  // declared by the PLC or a reference move: no contact, F_ext = 0
};

/// Why drift_warning is set (README "Digital twin"). Latched with the warning. Judged only on
/// stretches with a known external force (free moves), never on the load cell.
enum class DriftReason : int {
  none = 0,
  gain_fell = 1,      // the coupling gain fell from its reference (gain and friction separated)
  gain_rose = 2,      // … rose
  friction_rose = 3,  // the sliding friction rose (separated from the gain)
  friction_fell = 4,  // … fell
  error_rose = 5,     // the estimate's error grew: gain fell or friction rose, not separable
  error_fell = 6,     // … shrank the other way: gain rose or friction fell, not separable
};
/// Whether the recording or the run so far lets the drift be judged at all.
enum class DriftObservability : int {
  none = 0,       // no stretch with a known external force yet: drift not observable
  reference = 1,  // known-force stretches seen, the reference is still being formed
  tracking = 2,   // reference formed: drift is tracked against it
};
/// Change of the force estimate's error since the reference, from the known-force stretches:
/// error = estimate − true output force in the direction of motion (+: the estimate overstates).
struct DriftFigures {
  double zero_load_n = std::numeric_limits<double>::quiet_NaN();  // sliding at zero load
  double zero_load_se_n = 0.0;
  double rated_n = std::numeric_limits<double>::quiet_NaN();  // at the rated force (separable)
  double rated_se_n = 0.0;
  double rated_worst_n = std::numeric_limits<double>::quiet_NaN();  // not separable: all of the
                                                                    // zero-load change as gain
  double gain_change = std::numeric_limits<double>::quiet_NaN();    // Δg (relative), separable
  double gain_change_se = 0.0;
  double friction_change_n = std::numeric_limits<double>::quiet_NaN();  // ΔF_f, separable
  double friction_change_se_n = 0.0;
  double rated_force_n = 0.0;  // the rated force the second figure is given at
  bool separable = false;      // the moves separate gain from friction (accelerations, speeds)
};
/// Why healthy is false (not latched: it follows the measurements).
enum class HealthReason : int {
  none = 0,
  position_residual = 1,  // measured − predicted position beyond tolerance for a whole window
  step_out = 2,           // the nut stepped out (latched until re-sync)
  solver = 3,             // a SUNDIALS call failed this tick
};
/// Why step_out_warning is set.
enum class StepOutReason : int {
  none = 0,
  lookahead_crosses_edge = 1,  // the look-ahead's φ leaves the stable branch within lookahead_s
  setpoint_beyond_peak = 2,    // the force setpoint's trend passes the calibrated peak
  stepped_out = 3,             // the step-out flag itself (latched until re-sync)
};

struct TwinOutputs {
  double predicted_nut_pos_m = 0.0;         // twin's nut position (model driven by θ, F̂_ext)
  double predicted_output_force_n = 0.0;    // twin's output force F_out = −F_ext it carries
  double dynamic_output_force_est_n = 0.0;  // observer estimate of F_out (M p̈ + C ṗ + friction)
  double static_output_force_est_n = 0.0;   // paper eq. 6 on the same samples, for comparison
  double residual_pos_m = 0.0;              // measured − predicted nut position
  double residual_force_n = 0.0;            // dynamic − static estimate (drift statistic input)
  double phase_rad = 0.0;                   // measured φ, unwrapped
  double step_out_margin_rad = 0.0;         // π/2 − max |φ| over the look-ahead (<0: crossing)
  // Drift flag (known-force stretches only): change / margin (≥ 1, sustained: drift_warning).
  double drift_statistic = 0.0;
  DriftObservability drift_observability = DriftObservability::none;
  double drift_known_s = 0.0;  // known-force (free-move) time used since the reference restarted
  DriftFigures drift_now{};    // the current change (NaN until tracking)
  DriftFigures drift_at_warning{};
  // Load-cell check (only where one is logged; never used by the flag): coupling gain g relative
  // to the model from strong-force slides, NaN until estimated.
  double drift_gain_estimate = std::numeric_limits<double>::quiet_NaN();   // current g
  double drift_gain_stderr = 0.0;                                          // its standard error
  double drift_reference_gain = std::numeric_limits<double>::quiet_NaN();  // early g (reference)
  double drift_reference_stderr = 0.0;
  double drift_reference_t_s = 0.0;  // mean time of the flag's reference stretch
  double drift_warning_t_s = 0.0;    // when the warning was raised
  DriftReason drift_reason = DriftReason::none;
  HealthReason health_reason = HealthReason::none;
  StepOutReason step_out_reason = StepOutReason::none;
  bool healthy = true;            // the twin explains the measurements within their resolution
  bool drift_warning = false;     // the estimate's error moved from its reference (latched)
  bool step_out = false;          // φ left the stable branch / nut slipped a lead (latched)
  bool step_out_warning = false;  // look-ahead crosses ±π/2 (not latched)
  int slips = 0;                  // signed number of leads slipped since reset
  int friction_mode = 0;          // observer's mode: −1 sliding −p, 0 stuck, +1 sliding +p
  bool solver_ok = true;          // every SUNDIALS call of this tick succeeded
};

struct TwinMonitorConfig {
  ActuatorParams actuator;       // geometry, encoders, sample rate
  ForceCalibration calibration;  // the controller's calibration (periodic model used)
  TwinModel model;               // mass, friction, extra terms (config/model.toml)
  IntegratorOptions integrator;  // CVODE settings of the twin (step cap = sample period)
  // Observer. While the nut sticks its friction is unknown within ± break-away, so the external
  // force needs a prior (the same the loop's load observer uses for a load nothing holds).
  UnheldLoadPrior load_prior;
  // How well a slide's end pins the load: the model's force error while sliding, the same figure
  // the loop's load observer uses (serve and estimate pass [control]
  // observer_model_uncertainty_n; one default, not two copies of 0.3 N).
  double stop_force_sd_n = LoadObserverConfig{}.model_uncertainty_n;
  StopRule stop;                          // when the nut counts as stopped (as the observer)
  double resync_s = 0.020;                // twin runs open loop this long, then re-syncs
  double lookahead_s = 0.050;             // step-out warning horizon
  int lookahead_every_ticks = 10;         // look-ahead cadence (its cost is ~horizon/cap steps)
  double step_out_warn_margin_rad = 0.0;  // warn when look-ahead |φ| exceeds the edge − this
  // Drift detector: recursive least squares of the coupling gain g with nuisance terms, on
  // excitation-rich ticks only (monitor.cpp gain_tick; README "Digital twin").
  double drift_block_s = 0.020;    // ticks averaged into one least-squares sample
  double drift_memory_s = 4.0;     // forgetting time constant, in excitation-rich time
  double drift_reference_s = 5.0;  // excitation-rich time that makes the early reference
  double drift_sigmas = 4.0;       // significance: combined standard errors of g and g_ref
  double drift_min_change = 0.03;  // physical: relative change of g worth an operator's action
  double drift_sustain_s = 2.0;    // both must hold this long
  double drift_min_force_counts = 10.0;  // |F_m| ≥ this many counts' worth of force (≈ 11 N)
  double drift_phase_fraction = 0.75;    // |φ| within this fraction of the stable branch
  double drift_settle_s = 0.010;         // skip this long after the nut breaks loose
  int drift_min_edges = 3;               // … and until the encoder has counted this many edges
  double drift_end_exclusion_m = std::numeric_limits<double>::quiet_NaN();  // NaN: one lead
  // The flag: free moves (no contact), declared (TwinInputs::free_move) or recognised where the
  // no-load hypothesis fits: not in force control, the screw driving the nut (nut speed within
  // this fraction of the screw's), and the observer's external force within the model's
  // friction (undeclared only). The drift is the change of the estimate's error at zero load
  // and at the rated force, warned at drift_min_change of the rated force.
  double drift_free_memory_s = 8.0;        // forgetting time constant, in known-force time
  double drift_free_reference_s = 1.0;     // known-force time before the reference may form (one
                                           // reference move's worth), longer until precise
  double drift_free_speed_fraction = 0.5;  // over 20 ms: |v_nut − v_screw| ≤ this × |v_nut|
  double drift_rated_force_n = std::numeric_limits<double>::quiet_NaN();  // NaN: the safe force
                                                                          // (actuator × peak)
  // … and in force control, from the load the loop presses where it is passive (the same force
  // at the same nut position; twin/src/passive_drift.hpp): the first windows of force-control
  // time map the estimate over position, later ones are compared with the map where they go.
  double drift_passive_window_s = 2.0;     // force-control time per window
  double drift_passive_reference_s = 4.0;  // accepted windows' time that forms the map
  double drift_passive_bin_counts = 4.0;   // the map's cells, in linear counts
  // Health: the twin's prediction at the end of an open-loop interval (resync_s) misses the
  // measured position by more than this many linear counts, in this many intervals in a row.
  double healthy_residual_counts = 3.0;
  int healthy_intervals = 3;
  // … where the nut or the twin stuck or slipped in the interval, plus the screw's travel over
  // this long: the stick-slip of a move against a stiff spring ends its sticks chaotically, and
  // a twin equal to the plant times them up to about 5 ms apart (at 30 and 50 mm/s).
  double healthy_stick_timing_s = 0.006;
  // The open-loop twin (CVODE): the predicted nut position and force, the health verdict and the
  // step-out look-ahead. The force estimate is the observer's and does not need it; off, those
  // outputs read NaN / healthy and a tick costs the observer alone (the analysis's twin check).
  bool open_loop_twin = true;
};

/// What an operator reads for a raised drift warning, e.g. "force estimate error +0.45 ± 0.05 N
/// at zero load, +1.42 ± 0.11 N at 35.6 N over 40 s: coupling gain fell by 0.031 ± 0.003" (the
/// change from the reference stretch to the warning, combined standard errors). Empty without.
std::string drift_message(const TwinOutputs& o);
/// The same figures for any DriftFigures (twin-check prints the state at the end of a run).
std::string drift_figures_text(const DriftFigures& f);

class TwinMonitor {
 public:
  explicit TwinMonitor(const TwinMonitorConfig& config);
  ~TwinMonitor();
  TwinMonitor(const TwinMonitor&) = delete;
  TwinMonitor& operator=(const TwinMonitor&) = delete;

  /// Re-synchronises to a measured state (start-up, after re-homing or step-out re-sync):
  /// clears the latched flags and the drift statistic.
  void reset(double t_s, double screw_angle_rad, double nut_pos_m);
  /// Clears the drift warning and forgets the gain history: the next excitation-rich stretch
  /// becomes the new reference (operator: `maglead reset`, i.e. a fault_reset edge).
  void clear_drift() noexcept;
  /// One control tick. Call at the sample rate with strictly increasing t_s.
  TwinOutputs step(const TwinInputs& in) noexcept;

  const TwinMonitorConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace maglead::twin
