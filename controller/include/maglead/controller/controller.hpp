#pragma once
// The control loop's one cycle: read encoders, compute phase and force, run the drive state
// machine and the active mode, command the motor, publish a snapshot. Time comes from the
// caller (LoopRunner in service, a fake clock in tests); no allocation or lock in step().
#include <array>
#include <atomic>
#include <cstdint>
#include <limits>

#include "maglead/controller/detail/seqlock.hpp"
#include "maglead/controller/force_loop.hpp"
#include "maglead/controller/ports/hardware.hpp"
#include "maglead/controller/ports/twin_hook.hpp"
#include "maglead/controller/reference_move.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/physics/estimator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/physics/friction_model.hpp"
#include "maglead/physics/load_observer.hpp"
#include "maglead/registers/registers.hpp"

namespace maglead::controller {

/// What the drive does when a fault latches (CiA 402's fault-reaction option code, Festo's
/// "fault reaction"), chosen per cause.
enum class FaultReaction : std::uint8_t {
  mode_default = 0,  // force mode: release; position and idle: hold
  release = 1,  // ramp the output force to zero at release_rate_n_per_s, then stay at zero force
  hold = 2,     // hold position (a running move decelerates at its acceleration limit first)
  disable = 3,  // zero force at once (the screw follows the nut)
};
struct FaultReactions {
  FaultReaction watchdog = FaultReaction::mode_default;
  FaultReaction owner_lost = FaultReaction::mode_default;
  FaultReaction sensor_fault = FaultReaction::mode_default;
  FaultReaction step_out = FaultReaction::mode_default;
  double release_rate_n_per_s = 100.0;  // force ramp of "release"
};

struct ControllerConfig {
  ActuatorParams actuator;
  ForceCalibration calibration = paper_calibration();
  double velocity_limit_m_s = 0.01;  // profile defaults until a client writes its own
  double accel_limit_m_s2 = 0.1;
  double watchdog_s = 0.0;  // 0: communication watchdog off
  // "in position" / "force reached": |target − measured| or |setpoint − estimate| within the
  // tolerance, continuously for settle_s ([control] in config/actuator.toml, README "Status").
  double in_position_tol_m = 50e-6;  // about two linear-encoder counts
  double force_tol_n = 1.5;          // about one count of phase near φ = 0, plus noise
  double settle_s = 0.05;            // "reached" must hold this long
  // Force mode's stroke window: this far inside each stroke end a nut heading out is held
  // (force_limited, no fault); the hard stroke_limit fault stays for a nut pushed beyond.
  double force_stroke_margin_m = 1e-3;
  // Force mode's speed limit: the fastest the force loop lets the nut slide towards its
  // setpoint (force_limited, force_reached_reason speed_limit while it acts).
  double force_speed_limit_m_s = 0.1;
  // Position loop: phase correction per metre of error, and its integral action.
  double position_gain_rad_per_m = 1500.0;
  double position_integral_rad_per_m_s = 12000.0;
  // The model's friction, offset and mass (the model file's terms, twin::friction_model): the
  // load observer's force balance and the force loop's feed-forward.
  FrictionModel friction;
  // The model's coupling_gain_error g (a magnet that lost strength) and angle_ripple: the loop,
  // the observer and the static estimate use g times the calibration, the observer the ripple
  // too; the twin applies the model's terms itself.
  CouplingModel coupling;
  double force_damping_n_s_per_m = 60.0;      // force loop damping D while the nut slides
  double breakaway_ramp_n_per_s = 200.0;      // drive ramp that breaks a stuck nut loose
  double observer_model_uncertainty_n = 0.3;  // the model's force error while sliding
  double load_drift_n_per_s = 0.0;     // how fast a pressed load may change on its own (0 passive)
  double phase_tracking_per_s = 50.0;  // force mode: integral gain on the missed phase
  FaultReactions reactions;
  ReferenceMoveConfig reference_move;  // mode_command 3 ([reference_move] in actuator.toml)
};

/// The load observer a controller with this configuration runs (also for offline estimates).
LoadObserverConfig observer_config(const ControllerConfig& c);

/// Everything a client can read, from one cycle.
/// Why in_position is clear (IR 94; the codes' texts are in registers/).
enum class InPositionReason : std::uint16_t {
  reached = 0,
  not_holding = 1,     // disabled, in fault, or in force mode
  moving = 2,          // the profile still runs
  settling = 3,        // the profile at its target, the nut not yet within tolerance for the dwell
  coupling_limit = 4,  // the coupling at its safe limit and the nut stalled short of the target
};

struct Snapshot {
  std::uint64_t cycle = 0;
  bool actuator_read = false;  // nut_pos_m is a measurement (the loop has read the actuator)
  double t_s = 0.0;
  double nut_pos_m = 0.0, nut_vel_m_s = 0.0, screw_angle_rad = 0.0, phase_rad = 0.0;
  double force_est_n = 0.0,
         load_cell_force_n = 0.0;  // paper eq. 6; load cell (checking only, NaN: none)
  // The load observer: output force at the load and the interval consistent with what it saw.
  double observer_force_n = 0.0, observer_force_lo_n = 0.0, observer_force_hi_n = 0.0;
  std::uint16_t observer_basis = 0, force_loop_state = 0, force_reached_reason = 1;
  double profile_pos_m = 0.0, active_force_setpoint_n = 0.0, active_target_pos_m = 0.0;
  double period_s = 0.0, late_max_s = 0.0;
  std::uint64_t overrun_count = 0;
  TwinReport twin;
  std::uint16_t status_word = 0, alarm_code = 0, step_out_count = 0, drive_state = 0;
  std::uint16_t active_mode = 0, command_status = 0, reject_reason = 0;
  std::uint16_t fault_reaction = 0;      // registers::Reaction
  std::uint16_t in_position_reason = 1;  // InPositionReason
  // A drive_fault's cause and the drive's error code, latched with the alarm.
  std::uint16_t drive_fault_cause = 0, drive_error_code = 0;
};

/// The client-writable image (SI units), posted whole on every change so the loop sees every
/// control-word value in order and detects edges itself.
struct CommandImage {
  std::uint16_t control_word = 0;
  std::uint16_t mode_command = 0;
  std::uint16_t heartbeat = 0;  // last value written (any write counts)
  double watchdog_s = 0.0;
  double force_setpoint_n = 0.0;
  double position_setpoint_m = 0.02;
  double velocity_limit_m_s = 0.01;
  double accel_limit_m_s2 = 0.1;
  // Member-wise: the padding after the three words is not part of the value.
  bool operator==(const CommandImage&) const = default;
};
struct Command {
  CommandImage image;
  bool heartbeat = false;  // the heartbeat register was written (feeds the watchdog)
  bool owner_lost =
      false;  // the owner's connection closed: fault reaction if enabled, before the image
};

enum class CycleStatus : std::uint8_t { ok, hardware_error };

class Controller {
 public:
  /// Throws std::invalid_argument on an inconsistent configuration.
  Controller(const ControllerConfig& config, ActuatorHardware& hardware);

  /// Attach before the loop starts; nullptr detaches.
  void attach_twin(TwinHook* twin) noexcept { twin_ = twin; }

  /// One control cycle at time now_s (loop thread only). late_s: how late this cycle started.
  CycleStatus step(double now_s, double late_s = 0.0) noexcept;

  /// Commands a cycle takes at most: a flood of writes cannot stretch the cycle.
  static constexpr int kCommandsPerCycle = 64;
  /// Network side: queue a command for the next cycle. False when the queue is full.
  /// Callers on several threads must serialise.
  bool post(const Command& command) noexcept { return commands_.push(command); }
  /// Network side, when posting an owner_lost command failed (queue full): the loop reacts at
  /// its next cycle all the same. Lock-free.
  void signal_owner_lost() noexcept { owner_lost_flag_.store(true, std::memory_order_release); }
  Snapshot snapshot() const noexcept { return published_.load(); }

  const ControllerConfig& config() const noexcept { return cfg_; }
  /// The command image the loop starts from (defaults of the configuration).
  CommandImage initial_image() const noexcept;
  /// The force setpoint limit in the direction of `force_n` (signed), from the calibration.
  double safe_force_limit_n(double force_n) const noexcept;
  /// Force mode's stroke window [lo, hi] (force_stroke_margin_m inside each stroke end).
  struct Window {
    double lo_m, hi_m;
  };
  Window force_window() const noexcept;

 private:
  /// What the active mode reached this cycle (before the settle time).
  struct Reached {
    bool position = false, force = false;
  };
  // The cycle's stages, in the order step() runs them.
  double advance_clock(double now_s, double late_s) noexcept;
  void read_measurements(double now_s, const SensorSample& sample) noexcept;
  void take_commands() noexcept;
  void step_twin(double now_s) noexcept;
  void supervise(double now_s) noexcept;
  Reached control_by_state(double dt) noexcept;
  void fault_reaction_command(double dt) noexcept;
  double force_mode_command_rad(double dt, Reached& reached) noexcept;
  void check_force_window() noexcept;
  void release_window_end() noexcept;
  void update_mean_speed(double t_s, double pos_m) noexcept;
  double window_hold_command_rad(double dt) noexcept;
  void resync_to_nut() noexcept;
  void note_drive_fault_cause() noexcept;
  void update_position_limit(double dt) noexcept;
  bool settle(const Reached& reached, double dt) noexcept;
  HwStatus update_power() noexcept;
  void publish(bool settled, const Reached& reached) noexcept;
  InPositionReason in_position_reason(bool settled, const Reached& r) const noexcept;

  void apply(const Command& c) noexcept;
  void on_execute() noexcept;
  void latch_fault(registers::Alarm alarm) noexcept;
  void start_hold() noexcept;
  void controlled_stop() noexcept;
  void run_profile(double dt) noexcept;
  double force_command_rad(double dt) noexcept;
  double phase_for_drive_rad(double drive_n) const noexcept;
  void publish_observer() noexcept;
  /// Starts the reference move's next leg (a position target at its speed), if any.
  bool next_reference_leg() noexcept;
  double position_command_rad(double dt) noexcept;
  double position_command_rad(double dt, double lo_rad, double hi_rad) noexcept;
  bool waiting_for_nut(double gain_rad_per_m) const noexcept;
  void start_force_loop(bool afresh) noexcept;
  void reject(registers::Reject why) noexcept;
  void on_fault_reset() noexcept;
  void confirm_reset() noexcept;
  void on_owner_lost() noexcept;
  FaultReaction configured_reaction(registers::Alarm alarm) const noexcept;

  ControllerConfig cfg_;
  ActuatorHardware& hw_;
  TwinHook* twin_ = nullptr;
  EncoderVelocityEstimator velocity_;
  StaticForceEstimator estimator_;
  LoadForceObserver observer_;
  ForceLoop force_loop_;
  LoadEstimate load_{};
  detail::SpscQueue<Command, 1024> commands_;
  detail::SeqLock<Snapshot> published_;
  std::atomic<bool> owner_lost_flag_{false};
  double phase_lo_rad_ = 0.0, phase_hi_rad_ = 0.0;  // commandable phase range (safe forces)

  // Loop state (loop thread only).
  Snapshot s_{};
  CommandImage image_{};
  bool synced_ = false;
  double last_t_s_ = 0.0, last_heartbeat_s_ = 0.0;
  double phase_offset_rad_ = 0.0;  // whole leads the nut slipped, taken up by resync
  double last_phase_rad_ = 0.0;
  double steady_phase_rad_ = 0.0;       // the phase the nut last stood at (kResetSettle_s)
  double phase_steady_since_s_ = -1e9;  // since when the phase stays near steady_phase_rad_
  registers::DriveState state_ = registers::DriveState::disabled;
  registers::Mode mode_ = registers::Mode::idle;
  bool stopping_ = false, watchdog_expired_ = false, stepped_out_ = false, execute_pending_ = false;
  double screw_cmd_rad_ = 0.0;
  double target_m_ = 0.0, prof_pos_m_ = 0.0, prof_vel_m_s_ = 0.0, integral_rad_ = 0.0;
  double vmax_ = 0.01, amax_ = 0.1;
  double force_set_n_ = 0.0, drive_n_ = 0.0;  // force setpoint; coupling drive commanded
  double phase_track_rad_ = 0.0;              // integral of the phase the coupling missed
  ReferenceMove ref_move_;  // runs as position legs; the twin is told the nut is free
  double load_cell_reading_n_ =
      std::numeric_limits<double>::quiet_NaN();  // last load-cell sample (twin)
  double settled_s_ = 0.0;
  std::uint16_t command_bits_ = 0;
  // Fault reaction in progress (fault state only).
  registers::Reaction reaction_ = registers::Reaction::none;
  bool fault_position_hold_ = false;  // hold: the position loop keeps running (controlled stop)
  double release_force_n_ = 0.0;      // release: the output force being ramped to zero
  double lead_rad_ = 0.0;             // after a slip: the lead (2π k) the nut sits in now
  bool position_clamped_ = false;     // the position loop's phase command at the safe limit
  bool position_limited_ = false;     // …and the nut stalled there (force_limited)
  double stall_s_ = 0.0;
  int window_end_ = 0;  // force mode held at its window's end: +1 the far end, -1 the near one
  double position_phase_rad_ = 0.0;  // the position loop's last phase command
  bool hold_settled_ = false;        // the nut has stood still since the window's hold began
  bool hold_at_setpoint_ = false;    // the window's hold pushes towards its end at the setpoint
  // The nut's positions of the last samples (a ring): its mean speed over them, which the
  // window's look-ahead reads (one sample's speed moves in steps of a count per sample).
  static constexpr int kMeanSpeedSamples = 20;
  struct Sample {
    double t_s = 0.0, pos_m = 0.0;
  };
  std::array<Sample, kMeanSpeedSamples + 1> recent_{};
  int recent_next_ = 0, recent_count_ = 0;
  double mean_vel_m_s_ = 0.0;
  // The power stage: the last request made of the hardware, and a reset it still has to pass on.
  PowerRequest power_ = PowerRequest::disable;
  bool drive_reset_pending_ = false;
  // A fault reset is done only once the fault has stayed away this many more cycles.
  int reset_confirm_cycles_ = 0;
};

}  // namespace maglead::controller
