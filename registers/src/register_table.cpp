// The register table itself. Addresses are fixed once released: integrators' PLC programs
// depend on them. Input and holding addresses never overlap, so FC3 can read both (a PLC
// exchanges control and status in one FC23).
#include <algorithm>
#include <array>
#include <limits>

#include "maglead/registers/registers.hpp"

namespace maglead::registers {
namespace {

constexpr auto IR = Table::input_register;
constexpr auto HR = Table::holding_register;
constexpr auto CO = Table::coil;
constexpr auto DI = Table::discrete_input;
constexpr auto RO = Access::read_only;
constexpr auto RW = Access::read_write;
constexpr double kU16Max = 65535.0;
constexpr double kI32 = 2147483647.0;
constexpr double kU32Max = 4294967295.0;

constexpr std::array kTable = std::to_array<Register>({
    // Identity and word-order probes.
    {"device_type", IR, 0, Type::u16, 1, "", RO, 0, kU16Max, "Device type: 0x4D4C (\"ML\")"},
    {"firmware_version", IR, 1, Type::u16, 1, "", RO, 0, kU16Max,
     "Firmware version, major*256 + minor"},
    {"register_map_version", IR, 2, Type::u16, 1, "", RO, 0, kU16Max,
     "Version of this register map"},
    {"loop_rate_hz", IR, 3, Type::u16, 1, "Hz", RO, 0, kU16Max, "Control loop rate"},
    {"word_order_probe_u32", IR, 4, Type::u32, 1, "", RO, 0, kU32Max,
     "Always 0x12345678: reads 0x1234, 0x5678 when the word order is right"},
    {"word_order_probe_f32", IR, 6, Type::f32, 1, "", RO, -1e9, 1e9,
     "Always 1234.5678 as float32 (0x449A522B)"},
    // Drive status.
    {"status_word", IR, 10, Type::u16, 1, "", RO, 0, kU16Max, "Status bits, see discrete inputs"},
    {"alarm_code", IR, 11, Type::u16, 1, "", RO, 0, kU16Max,
     "Latched alarm, see alarm codes (0 none)"},
    {"step_out_count", IR, 12, Type::u16, 1, "", RO, 0, kU16Max, "Step-outs detected since start"},
    {"drive_state", IR, 13, Type::u16, 1, "", RO, 0, 3, "0 disabled, 1 ready, 2 enabled, 3 fault"},
    {"active_mode", IR, 14, Type::u16, 1, "", RO, 0, 2, "0 idle (hold), 1 position, 2 force"},
    {"command_status", IR, 15, Type::u16, 1, "", RO, 0, kU16Max,
     "Command handshake bits: 0 execute ack, 1 execute done, 2 reset ack, 3 reset done, "
     "4 resync ack, 5 resync done, 6 last command rejected. A command clears only its own bits "
     "and 6, so another's stay (reset done through later executes): test the bits you wait for "
     "with a mask, never the whole word"},
    {"command_reject_reason", IR, 16, Type::u16, 1, "", RO, 0, kU16Max,
     "Why the last edge command was rejected, see reject codes"},
    {"control_owner", IR, 17, Type::u16, 1, "", RO, 0, kU16Max,
     "Client that owns control (0 none; TCP connection number, 65535 the RTU master)"},
    {"control_owner_ipv4", IR, 18, Type::u32, 1, "", RO, 0, kU32Max,
     "IPv4 address of the owning TCP client (0 none)"},
    {"nut_pos_um", IR, 20, Type::i32, 1e-6, "m", RO, -kI32 * 1e-6, kI32 * 1e-6,
     "Measured nut position"},
    {"nut_vel_um_s", IR, 22, Type::i32, 1e-6, "m/s", RO, -kI32 * 1e-6, kI32 * 1e-6, "Nut velocity"},
    {"screw_angle_urad", IR, 24, Type::i32, 1e-6, "rad", RO, -kI32 * 1e-6, kI32 * 1e-6,
     "Screw angle (motor encoder / gear ratio)"},
    {"phase_urad", IR, 26, Type::i32, 1e-6, "rad", RO, -kI32 * 1e-6, kI32 * 1e-6,
     "Phase difference phi = theta - 2 pi p / L"},
    {"force_est_mn", IR, 28, Type::i32, 1e-3, "N", RO, -kI32 * 1e-3, kI32 * 1e-3,
     "Estimated output force F_out (paper eq. 6), + pushes along +p"},
    {"load_cell_force_mn", IR, 30, Type::i32, 1e-3, "N", RO, -kI32 * 1e-3, kI32 * 1e-3,
     "Output force from the load cell (-load force), 0 without one (then "
     "load_cell_force_n_f32 is NaN)"},
    {"profile_pos_um", IR, 32, Type::i32, 1e-6, "m", RO, -kI32 * 1e-6, kI32 * 1e-6,
     "Position reference of the motion profile now"},
    {"active_force_setpoint_mn", IR, 34, Type::i32, 1e-3, "N", RO, -kI32 * 1e-3, kI32 * 1e-3,
     "Force setpoint the drive holds (force mode)"},
    {"active_target_pos_um", IR, 36, Type::i32, 1e-6, "m", RO, -kI32 * 1e-6, kI32 * 1e-6,
     "Target of the current move (position mode)"},
    {"twin_pred_nut_pos_um", IR, 38, Type::i32, 1e-6, "m", RO, -kI32 * 1e-6, kI32 * 1e-6,
     "Twin: predicted nut position (0 without twin)"},
    {"twin_pred_force_mn", IR, 40, Type::i32, 1e-3, "N", RO, -kI32 * 1e-3, kI32 * 1e-3,
     "Twin: predicted output force (0 without twin)"},
    {"twin_residual_pos_um", IR, 42, Type::i32, 1e-6, "m", RO, -kI32 * 1e-6, kI32 * 1e-6,
     "Twin: measured minus predicted nut position"},
    {"twin_residual_force_mn", IR, 44, Type::i32, 1e-3, "N", RO, -kI32 * 1e-3, kI32 * 1e-3,
     "Twin: force residual (dynamic estimate, IR 46, minus the twin's prediction, IR 40)"},
    {"twin_dynamic_force_mn", IR, 46, Type::i32, 1e-3, "N", RO, -kI32 * 1e-3, kI32 * 1e-3,
     "Twin: dynamic output-force estimate (observer)"},
    {"loop_cycle_count", IR, 48, Type::u32, 1, "", RO, 0, kU32Max, "Control cycles run (wraps)"},
    {"loop_overrun_count", IR, 50, Type::u32, 1, "", RO, 0, kU32Max,
     "Cycles that started more than one period late"},
    {"loop_period_us", IR, 52, Type::u16, 1e-6, "s", RO, 0, kU16Max * 1e-6,
     "Last loop period; stays at 65535 µs when longer"},
    {"loop_late_max_us", IR, 53, Type::u16, 1e-6, "s", RO, 0, kU16Max * 1e-6,
     "Largest lateness of a cycle start since start; stays at 65535 µs when larger (serve's "
     "overrun lines print the full figure)"},
    {"fault_reaction", IR, 54, Type::u16, 1, "", RO, 0, 3,
     "Fault reaction in progress, see fault reactions (0 none)"},
    {"write_refusal_reason", IR, 55, Type::u16, 1, "", RO, 0, kU16Max,
     "Why the last refused write (exception 03 or 04) was refused, see write refusals (0 none; "
     "kept until the next refusal). A refused write changes nothing: the setpoint staged before "
     "it stays, and the next execute applies that one"},
    {"twin_drift_reason", IR, 56, Type::u16, 1, "", RO, 0, 6,
     "Twin: why drift_warning is set, judged on free moves and on a passive load the force loop "
     "revisits (never the load cell): 0 none, "
     "1 coupling gain fell, 2 gain rose, 3 friction rose, 4 friction fell, 5 estimate error rose "
     "(gain fell or friction rose: not separable), 6 error fell (gain rose or friction fell) "
     "(latched with the warning; fault_reset clears both)"},
    {"twin_health_reason", IR, 57, Type::u16, 1, "", RO, 0, 3,
     "Twin: why twin_healthy is off: 0 healthy, 1 position residual beyond tolerance, "
     "2 stepped out, 3 solver error"},
    {"twin_step_out_reason", IR, 58, Type::u16, 1, "", RO, 0, 3,
     "Twin: why step_out_warning is set: 0 none, 1 look-ahead leaves the stable branch, "
     "2 setpoint trend beyond the calibrated peak, 3 stepped out"},
    {"force_loop_state", IR, 59, Type::u16, 1, "", RO, 0, 8,
     "Force loop: 0 off (not force mode), 1 breaking a stuck nut loose, 2 approaching the "
     "setpoint (sliding, friction fed forward), 3 landing, 4 holding (load force at the "
     "setpoint, coupling mid stick band), 5 holding without motion (the setpoint was already "
     "inside the known load-force bound), 6 blocked (no motion at twice the model's break-away), "
     "7 held at the end of the force mode's stroke window, 8 sliding at the force speed limit"},
    {"load_force_est_mn", IR, 60, Type::i32, 1e-3, "N", RO, -1e6, 1e6,
     "Load observer: output force at the load, from phase and encoder only (no load cell): the "
     "force balance while the nut slides, the force it had when it stopped while it sticks"},
    {"load_force_lo_mn", IR, 62, Type::i32, 1e-3, "N", RO, -1e6, 1e6,
     "Load observer: lowest output force consistent with what it has seen (the bound)"},
    {"load_force_hi_mn", IR, 64, Type::i32, 1e-3, "N", RO, -1e6, 1e6,
     "Load observer: highest output force consistent with what it has seen"},
    {"force_reached_reason", IR, 66, Type::u16, 1, "", RO, 0, 9,
     "Why force_reached is clear, see its codes (0 reached)"},
    {"observer_basis", IR, 67, Type::u16, 1, "", RO, 0, 2,
     "Load observer: what pins the estimate down: 0 only the stick band (load force anywhere in "
     "drive +- break-away), 1 sliding (force balance), 2 stuck after a slide"},
    {"drive_fault_cause", IR, 68, Type::u16, 1, "", RO, 0, 6,
     "With alarm drive_fault: why the drive faulted, see its codes (0 none, or a backend that "
     "cannot tell). It may sharpen after the latch (a silent drive's process data time out "
     "before its heartbeat: 3, then 2): read it again after the heartbeat timeout"},
    {"drive_error_code", IR, 69, Type::u16, 1, "", RO, 0, kU16Max,
     "With drive_fault_cause 1: the drive's own error code (CiA 402 object 0x603F or its EMCY; "
     "the drive's manual lists them), 0 none"},
    {"twin_gain_f32", IR, 70, Type::f32, 1, "", RO, -1e9, 1e9,
     "Twin, load-cell check (not used by the drift flag): coupling gain relative to the "
     "calibration from strong-force slides against the load cell (0 until estimated)"},
    {"twin_gain_stderr_f32", IR, 72, Type::f32, 1, "", RO, -1e9, 1e9,
     "Twin, load-cell check: standard error of that gain"},
    {"twin_gain_reference_f32", IR, 74, Type::f32, 1, "", RO, -1e9, 1e9,
     "Twin, load-cell check: early reference of that gain (0 until set)"},
    {"twin_drift_observability", IR, 76, Type::u16, 1, "", RO, 0, 2,
     "Twin drift flag: 0 not observable (no stretch with a known external force yet), "
     "1 free moves seen, reference forming, 2 tracking against the reference"},
    {"twin_drift_separable", IR, 77, Type::u16, 1, "", RO, 0, 1,
     "Twin drift flag: 1 if the moves separate coupling gain from friction"},
    {"twin_drift_zero_load_error_n_f32", IR, 78, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Twin drift: change of the force estimate's error at zero load since the reference "
     "(+: overstates, in the direction of motion; 0 until tracking)"},
    {"twin_drift_zero_load_stderr_n_f32", IR, 80, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Twin drift: standard error of that change"},
    {"twin_drift_rated_error_n_f32", IR, 82, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Twin drift: the change at the rated force (not separable: the worst case, all gain)"},
    {"twin_drift_rated_stderr_n_f32", IR, 84, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Twin drift: standard error of that change (0 when not separable)"},
    {"twin_drift_gain_change_f32", IR, 86, Type::f32, 1, "", RO, -1e9, 1e9,
     "Twin drift: change of the coupling gain since the reference (0 unless separable)"},
    {"twin_drift_friction_change_n_f32", IR, 88, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Twin drift: change of the sliding friction since the reference (0 unless separable)"},
    {"twin_drift_known_force_s_f32", IR, 90, Type::f32, 1, "s", RO, -1e9, 1e9,
     "Twin drift: free-move time used since the reference restarted"},
    {"twin_drift_statistic_f32", IR, 92, Type::f32, 1, "", RO, -1e9, 1e9,
     "Twin drift: change over its margin (1 or more for 2 s raises drift_warning)"},
    {"in_position_reason", IR, 94, Type::u16, 1, "", RO, 0, 4,
     "Why in_position is clear, see its codes (0 in position); 4 coupling_limit also sets "
     "force_limited"},
    // The same 32-bit values as float32, SI units.
    {"nut_pos_m_f32", IR, 100, Type::f32, 1, "m", RO, -1e9, 1e9, "Measured nut position"},
    {"nut_vel_m_s_f32", IR, 102, Type::f32, 1, "m/s", RO, -1e9, 1e9, "Nut velocity"},
    {"screw_angle_rad_f32", IR, 104, Type::f32, 1, "rad", RO, -1e9, 1e9, "Screw angle"},
    {"phase_rad_f32", IR, 106, Type::f32, 1, "rad", RO, -1e9, 1e9, "Phase difference phi"},
    {"force_est_n_f32", IR, 108, Type::f32, 1, "N", RO, -1e9, 1e9, "Estimated output force"},
    {"load_cell_force_n_f32", IR, 110, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Load-cell output force, NaN without a load cell (the cia402 backend)"},
    {"profile_pos_m_f32", IR, 112, Type::f32, 1, "m", RO, -1e9, 1e9, "Profile position reference"},
    {"active_force_setpoint_n_f32", IR, 114, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Force setpoint held"},
    {"active_target_pos_m_f32", IR, 116, Type::f32, 1, "m", RO, -1e9, 1e9, "Target of the move"},
    {"twin_pred_nut_pos_m_f32", IR, 118, Type::f32, 1, "m", RO, -1e9, 1e9,
     "Twin: predicted position"},
    {"twin_pred_force_n_f32", IR, 120, Type::f32, 1, "N", RO, -1e9, 1e9, "Twin: predicted force"},
    {"twin_residual_pos_m_f32", IR, 122, Type::f32, 1, "m", RO, -1e9, 1e9,
     "Twin: position residual"},
    {"twin_residual_force_n_f32", IR, 124, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Twin: force residual"},
    {"twin_dynamic_force_n_f32", IR, 126, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Twin: dynamic force estimate"},
    {"load_force_est_n_f32", IR, 128, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Load observer: output force at the load"},
    {"load_force_lo_n_f32", IR, 130, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Load observer: lowest output force consistent"},
    {"load_force_hi_n_f32", IR, 132, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Load observer: highest output force consistent"},
    // The drive's limits, from its configuration: what a PLC checks a setpoint against before
    // it writes one (a write beyond them is refused with exception 03).
    {"force_limit_push_n_f32", IR, 140, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Largest push force setpoint accepted: safe_force_fraction of the calibrated peak push"},
    {"force_limit_pull_n_f32", IR, 142, Type::f32, 1, "N", RO, -1e9, 1e9,
     "Largest pull force setpoint accepted (negative): safe_force_fraction of the peak pull"},
    {"stroke_min_m_f32", IR, 144, Type::f32, 1, "m", RO, -1e9, 1e9,
     "Lowest position setpoint accepted (the stroke's near end; enabled, a nut moving out more "
     "than 0.5 mm beyond either end faults)"},
    {"stroke_max_m_f32", IR, 146, Type::f32, 1, "m", RO, -1e9, 1e9,
     "Highest position setpoint accepted (the stroke's far end)"},
    {"force_window_min_m_f32", IR, 148, Type::f32, 1, "m", RO, -1e9, 1e9,
     "Force mode holds a nut heading below this (force_reached_reason 7, no fault)"},
    {"force_window_max_m_f32", IR, 150, Type::f32, 1, "m", RO, -1e9, 1e9,
     "Force mode holds a nut heading above this (force_reached_reason 7, no fault)"},
    {"force_speed_limit_m_s_f32", IR, 152, Type::f32, 1, "m/s", RO, -1e9, 1e9,
     "Fastest the force loop lets the nut slide (force_reached_reason 8 while it acts)"},
    // Commands and setpoints. Setpoints are staged: an execute edge applies them.
    {"control_word", HR, 1000, Type::u16, 1, "", RW, 0, 31,
     "Control bits, see coils; enable and stop are levels, the others act on rising edges; "
     "refused by broadcast"},
    {"mode_command", HR, 1001, Type::u16, 1, "", RW, 0, 3,
     "Mode the next execute edge applies: 0 idle (stop and hold), 1 position, 2 force, "
     "3 reference move (the twin's drift check); refused by broadcast"},
    {"heartbeat", HR, 1002, Type::u16, 1, "", RW, 0, kU16Max,
     "Write anything to feed the communication watchdog"},
    {"watchdog_ms", HR, 1003, Type::u16, 1e-3, "s", RW, 0, 60.0,
     "Communication watchdog time, 0 = off: while the drive is enabled, no heartbeat write for "
     "this long faults it (alarm 3, fault reaction). It counts from the enable edge (and from a "
     "write that changes it), and not at all while the drive is ready, disabled or in fault"},
    {"force_setpoint_mn", HR, 1004, Type::i32, 1e-3, "N", RW, -100.0, 100.0,
     "Output-force setpoint (also refused beyond the calibrated safe limit)"},
    {"position_setpoint_um", HR, 1006, Type::i32, 1e-6, "m", RW, 0.0, 0.040,
     "Target nut position (also refused outside the configured stroke); until a client writes "
     "one, where the nut is"},
    {"velocity_limit_um_s", HR, 1008, Type::i32, 1e-6, "m/s", RW, 1e-5, 0.1, "Profile speed limit"},
    {"accel_limit_um_s2", HR, 1010, Type::i32, 1e-6, "m/s^2", RW, 1e-4, 5.0,
     "Profile acceleration limit"},
    {"force_setpoint_n_f32", HR, 1012, Type::f32, 1, "N", RW, -100.0, 100.0,
     "Force setpoint, float32"},
    {"position_setpoint_m_f32", HR, 1014, Type::f32, 1, "m", RW, 0.0, 0.040,
     "Target position, float32"},
    {"velocity_limit_m_s_f32", HR, 1016, Type::f32, 1, "m/s", RW, 1e-5, 0.1,
     "Speed limit, float32"},
    {"accel_limit_m_s2_f32", HR, 1018, Type::f32, 1, "m/s^2", RW, 1e-4, 5.0,
     "Acceleration limit, float32"},
    // Control word bits as coils.
    {"enable", CO, kEnable, Type::bit, 1, "", RW, 0, 1,
     "Level: a rising edge claims control when nobody owns it and enables a ready drive; "
     "falling edge disables and releases control"},
    {"stop", CO, kStop, Type::bit, 1, "", RW, 0, 1, "Level: controlled stop and hold while set"},
    {"fault_reset", CO, kFaultReset, Type::bit, 1, "", RW, 0, 1, "Edge: clear a latched fault"},
    {"resync", CO, kResync, Type::bit, 1, "", RW, 0, 1,
     "Edge: re-synchronise the phase after a step-out (takes the nut's new lead as zero)"},
    {"execute", CO, kExecute, Type::bit, 1, "", RW, 0, 1,
     "Edge: apply mode_command with the staged setpoints (start a move, apply a force, stop)"},
    // Status word bits as discrete inputs.
    {"ready", DI, kReady, Type::bit, 1, "", RO, 0, 1, "Drive ready to enable"},
    {"enabled", DI, kEnabled, Type::bit, 1, "", RO, 0, 1, "Drive enabled, modes act"},
    {"fault", DI, kFault, Type::bit, 1, "", RO, 0, 1, "A fault is latched (alarm_code says which)"},
    {"moving", DI, kMoving, Type::bit, 1, "", RO, 0, 1, "Nut moving or a profile running"},
    {"in_position", DI, kInPosition, Type::bit, 1, "", RO, 0, 1,
     "Enabled and holding a position at its target within tolerance: position mode, a reference "
     "move's end, or idle's stop and hold (not in force mode)"},
    {"force_reached", DI, kForceReached, Type::bit, 1, "", RO, 0, 1,
     "Force mode: the load observer's whole bound lies within the tolerance of the setpoint "
     "for the dwell (the load force, not the coupling force); force_reached_reason says why not"},
    {"step_out", DI, kStepOut, Type::bit, 1, "", RO, 0, 1,
     "The nut stepped out; resync then reset"},
    {"drift_warning", DI, kDriftWarning, Type::bit, 1, "", RO, 0, 1,
     "Twin: calibration drift detected"},
    {"watchdog_expired", DI, kWatchdogExpired, Type::bit, 1, "", RO, 0, 1,
     "No heartbeat within watchdog_ms while the drive was enabled"},
    {"twin_healthy", DI, kTwinHealthy, Type::bit, 1, "", RO, 0, 1, "Twin running and consistent"},
    {"step_out_warning", DI, kStepOutWarning, Type::bit, 1, "", RO, 0, 1,
     "Twin: step-out predicted"},
    {"stopped", DI, kStopped, Type::bit, 1, "", RO, 0, 1,
     "Controlled stop active: the stop bit, or a fault reaction that stops and holds (a release "
     "reaction shows in fault_reaction instead)"},
    {"owned", DI, kOwned, Type::bit, 1, "", RO, 0, 1, "A client owns control"},
    {"stroke_limit", DI, kStrokeLimit, Type::bit, 1, "", RO, 0, 1, "Nut at a stroke end"},
    {"twin_lagging", DI, kTwinLagging, Type::bit, 1, "", RO, 0, 1,
     "Twin behind the loop: its input queue overflowed, or its results are older than the bound "
     "(5 cycles); the loop never waits for it"},
    {"force_limited", DI, kForceLimited, Type::bit, 1, "", RO, 0, 1,
     "The drive at its envelope: in force mode the nut held at the end of its stroke window "
     "before the force was reached (force_reached_reason 7), sliding at the force speed limit "
     "(reason 8), or stuck with the coupling at its safe limit short of the force (reason 9); "
     "in position mode the coupling at its safe limit with the nut stalled short of the target "
     "(in_position_reason 4); no fault: the next setpoint is taken at once"},
});

constexpr std::array kAlarms = std::to_array<Code>({
    {0, "none", "no alarm"},
    {1, "step_out", "phase left the stable branch: the nut slipped; force commanding stopped"},
    {2, "phase_jump", "phase jumped by more than pi in one cycle (sensor or slip)"},
    {3, "watchdog", "no heartbeat within watchdog_ms: fault reaction"},
    {4, "stroke_limit", "nut moving out more than 0.5 mm beyond the configured stroke"},
    {5, "sensor_fault", "actuator reported a sensor fault"},
    {6, "drive_fault", "the drive or its bus reported a fault (drive_fault_cause says which)"},
    {7, "owner_lost",
     "the connection that owned control closed: fault reaction; claim again with "
     "fault_reset, then an enable edge"},
    {8, "following_error",
     "the drive's motor did not follow the command within the drive's following error window "
     "(CiA 402 statusword bit 13): the last command is kept"},
});
constexpr std::array kReactions = std::to_array<Code>({
    {0, "none", "no fault reaction running"},
    {1, "releasing", "ramping the output force to zero"},
    {2, "holding", "holding position (a running move decelerates first)"},
    {3, "released", "zero output force: the screw follows the nut"},
    {4, "drive_own",
     "the drive faulted or fell silent: what the axis does is the drive's own fault reaction "
     "(CiA 402 object 0x605E); the controller keeps its last command until the fault reset"},
});
constexpr std::array kRefusals = std::to_array<Code>({
    {0, "none", "no write refused"},
    {1, "not_owner",
     "another client owns control: it must release it (enable low) or lose its connection"},
    {2, "broadcast_state_change", "control word and mode are not accepted by broadcast (unit 0)"},
    {3, "out_of_range",
     "exception 03: a value outside its register's range (maglead registers), an unknown "
     "control-word bit among them"},
    {4, "force_beyond_safe_limit",
     "exception 03: a force setpoint inside the register's range but beyond the safe limit "
     "(IR 140/142)"},
    {5, "position_outside_stroke",
     "exception 03: a position setpoint inside the register's range but outside a narrower "
     "configured stroke (IR 144/146)"},
    {6, "bad_control_word", "exception 03: execute with stop, fault_reset or resync"},
    {7, "word_order",
     "exception 03: a float32 setpoint that decodes to a subnormal value (not 0, below 1.2e-38 "
     "in size), which is what a round value sent low word first looks like (10.0 as 0, 16672): "
     "send the high word first (word_order_probe_f32, IR 6, checks a client)"},
    {8, "copies_disagree",
     "exception 03: one write carried both copies of a setpoint, the scaled integer and the "
     "float32, more than half the integer's unit apart (the commands block written back with one "
     "copy changed): change both, or write the one copy at its own address"},
});
constexpr std::array kRejects = std::to_array<Code>({
    {0, "none", "accepted"},
    {1, "not_enabled", "execute needs an enabled drive"},
    {2, "in_fault", "command refused while a fault is latched"},
    {3, "force_beyond_safe_limit", "force setpoint beyond the safe fraction of peak force"},
    {4, "target_outside_stroke", "position setpoint outside the stroke"},
    {5, "stopped",
     "execute refused while the stop bit is set (over Modbus the write carrying both is refused "
     "first: exception 03, write_refusal_reason 6)"},
    {6, "still_faulty",
     "fault reset refused: the cause is still present (after a slip: the phase off its stable "
     "branch, resync first, or not yet still for 0.1 s, wait until the nut stands)"},
    {7, "not_stepped_out", "resync only after a step-out"},
    {8, "fault_returned",
     "fault reset passed on, but a fault latched again before it was done: its cause persists "
     "(alarm_code says which)"},
});
constexpr std::array kStates = std::to_array<Code>({
    {0, "disabled", "not synchronised yet or the actuator reports an error"},
    {1, "ready", "holding position, waiting for an enable edge"},
    {2, "enabled", "modes act on commands"},
    {3, "fault", "latched until fault_reset"},
});
constexpr std::array kInPositionReasons = std::to_array<Code>({
    {0, "reached", "in position: at the target within tolerance for the dwell"},
    {1, "not_holding", "not holding a position: disabled, in fault, or in force mode"},
    {2, "moving", "the motion profile still runs towards the target"},
    {3, "settling", "the profile is at the target, the nut not yet within tolerance for the dwell"},
    {4, "coupling_limit",
     "the coupling is at its safe limit and the nut stalled short of the target: the load needs "
     "more force than the safe limit; no fault, the next setpoint is taken at once"},
});
constexpr std::array kDriveFaultCauses = std::to_array<Code>({
    {0, "none", "no drive fault, or a backend that cannot tell its cause"},
    {1, "drive_reports_fault",
     "the drive itself is in fault: drive_error_code says why (the drive's manual)"},
    {2, "drive_silent", "no heartbeat: the drive is off, unpowered or off the bus"},
    {3, "process_data_lost", "the drive's cyclic data stopped arriving: bus load or lost frames"},
    {4, "bus_off", "the CAN controller left the bus: wiring, termination, bit rate"},
    {5, "drive_restarted", "the drive reset itself while running (a boot-up message)"},
    {6, "enable_timeout", "an enable request did not reach operation enabled in time"},
});
constexpr std::array kModes = std::to_array<Code>({
    {0, "idle", "hold the screw where it is"},
    {1, "position", "move the nut to a target with speed and acceleration limits"},
    {2, "force", "hold an output-force setpoint"},
    {3, "reference_move",
     "back-and-forth at two speeds inside the configured window, nothing touching the nut: the "
     "twin judges estimation drift on it (then hold; active_mode reads 1 while it runs)"},
});

constexpr std::array kDriftReasons = std::to_array<Code>({
    {0, "none", "no drift warning"},
    {1, "gain_fell", "the coupling gain fell (gain and friction separated)"},
    {2, "gain_rose", "the coupling gain rose"},
    {3, "friction_rose", "the sliding friction rose (separated from the gain)"},
    {4, "friction_fell", "the sliding friction fell"},
    {5, "error_rose", "the estimate's error grew: gain fell or friction rose, not separable"},
    {6, "error_fell", "the error shrank: gain rose or friction fell, not separable"},
});
constexpr std::array kHealthReasons = std::to_array<Code>({
    {0, "none", "twin healthy"},
    {1, "position_residual", "measured minus predicted position beyond tolerance for a window"},
    {2, "step_out", "the nut stepped out (until a resync)"},
    {3, "solver", "a SUNDIALS call failed this tick"},
});
constexpr std::array kStepOutReasons = std::to_array<Code>({
    {0, "none", "no step-out warning"},
    {1, "lookahead_crosses_edge", "the look-ahead's phase leaves the stable branch"},
    {2, "setpoint_beyond_peak", "the force setpoint's trend passes the calibrated peak"},
    {3, "stepped_out", "the nut stepped out (until a resync)"},
});
constexpr std::array kForceLoopStates = std::to_array<Code>({
    {0, "off", "not in force mode"},
    {1, "breaking_away", "stuck off the setpoint: ramping the drive until the nut moves"},
    {2, "approaching", "sliding towards the setpoint, friction fed forward"},
    {3, "landing", "at the setpoint: friction stops the nut"},
    {4, "holding", "stuck with the load force at the setpoint, coupling mid stick band"},
    {5, "holding_no_motion", "the setpoint was already inside the known load-force bound"},
    {6, "blocked", "no motion at twice the model's break-away force"},
    {7, "held_at_stroke_end",
     "the nut was about to pass the force mode's stroke window end (50 ms ahead at its speed): "
     "held where it was"},
    {8, "speed_limited", "sliding towards the setpoint at the force mode's speed limit"},
});
constexpr std::array kReachedReasons = std::to_array<Code>({
    {0, "reached", "load force within the tolerance for the dwell"},
    {1, "not_force_mode", "not in force mode"},
    {2, "load_force_off", "the observer's load force is outside the tolerance"},
    {3, "bound_unknown", "load force unknown: nothing slid yet, or the load changed while stuck"},
    {4, "bound_too_wide", "the load-force bound is wider than the tolerance"},
    {5, "moving", "the nut slides: the load force is still changing"},
    {6, "settling", "inside the tolerance, the dwell is running"},
    {7, "stroke_end",
     "the stroke window ended before the force: the nut is held short of its end (up to 50 ms "
     "of its travel)"},
    {8, "speed_limit", "the nut slides towards the setpoint at the force mode's speed limit"},
    {9, "drive_limit",
     "the coupling is at its safe limit (safe_force_fraction of the peak) and the nut stuck short "
     "of the setpoint: friction takes up to F_c of the drive, so less reaches the load"},
});
constexpr std::array kObserverBases = std::to_array<Code>({
    {0, "stick_band", "only the stick band: load force anywhere in drive +- break-away"},
    {1, "sliding", "the nut slides: force balance"},
    {2, "stuck_after_slide", "stuck after a slide: the force it had when it stopped"},
});
constexpr std::array kDriftObservability = std::to_array<Code>({
    {0, "not_observable", "no stretch with a known external force yet"},
    {1, "reference_forming", "known-force stretches seen, the reference is being formed"},
    {2, "tracking", "the reference is formed: drift is tracked against it"},
});
constexpr std::array kDriftSeparable = std::to_array<Code>({
    {0, "not_separable", "the moves do not tell coupling gain from friction"},
    {1, "separable", "the moves tell coupling gain from friction"},
});

/// Every register that holds a code, with its list: poll, watch and the docs name each value.
struct CodeRegister {
  std::string_view register_name;
  std::span<const Code> codes;
};
const std::array kCodeRegisters = std::to_array<CodeRegister>({
    {"drive_state", kStates},
    {"drive_fault_cause", kDriveFaultCauses},
    {"active_mode", kModes},
    {"mode_command", kModes},
    {"alarm_code", kAlarms},
    {"command_reject_reason", kRejects},
    {"fault_reaction", kReactions},
    {"write_refusal_reason", kRefusals},
    {"twin_drift_reason", kDriftReasons},
    {"twin_health_reason", kHealthReasons},
    {"twin_step_out_reason", kStepOutReasons},
    {"force_loop_state", kForceLoopStates},
    {"force_reached_reason", kReachedReasons},
    {"in_position_reason", kInPositionReasons},
    {"observer_basis", kObserverBases},
    {"twin_drift_observability", kDriftObservability},
    {"twin_drift_separable", kDriftSeparable},
});

constexpr std::array kRanges = std::to_array<AddressRange>({
    {IR, 0, 154,
     "identity, status, measurements (scaled and float32), twin, loop, load observer, limits"},
    {HR, 1000, 20, "commands and setpoints"},
    {CO, 0, 5, "control word bits"},
    {DI, 0, 16, "status word bits"},
});
constexpr std::array kPollBlocks = std::to_array<AddressRange>({
    {IR, 0, 95,
     "FC4 (or FC3): identity, status, alarm, owner, scaled measurements, twin, loop, fault "
     "reaction, load observer and force loop, drift without a load cell, in-position reason"},
    {IR, 100, 54, "FC4 (or FC3): the same measurements as float32, and the drive's limits"},
    {HR, 1000, 20,
     "FC3: commands and setpoints as written (or FC23: write 1000.. and read 10..55 in one)"},
});

}  // namespace

std::span<const Register> table() { return kTable; }
std::span<const AddressRange> mapped_ranges() { return kRanges; }
std::span<const AddressRange> poll_blocks() { return kPollBlocks; }

bool in_mapped_range(Table t, std::uint16_t address) {
  for (const auto& r : kRanges)
    if (r.table == t && address >= r.first && address < r.first + r.count) return true;
  return false;
}
std::span<const Code> alarm_codes() { return kAlarms; }
std::span<const Code> reject_codes() { return kRejects; }
std::span<const Code> drive_states() { return kStates; }
std::span<const Code> modes() { return kModes; }
std::span<const Code> reactions() { return kReactions; }
std::span<const Code> refusals() { return kRefusals; }
std::span<const Code> command_bits() {
  static constexpr Code kBits[] = {
      {kExecuteAck, "execute_ack", "the controller took the execute edge (while execute is held)"},
      {kExecuteDone, "execute_done", "the executed target was reached and held for settle_s"},
      {kResetAck, "reset_ack", "the controller took the fault_reset edge"},
      {kResetDone, "reset_done",
       "the fault stayed away: the reset is done (kept until the next reset)"},
      {kResyncAck, "resync_ack", "the controller took the resync edge"},
      {kResyncDone, "resync_done", "the phase was taken again on the nearest lead"},
      {kRejected, "rejected", "the last edge command was rejected (command_reject_reason)"}};
  return kBits;
}
std::span<const Code> codes_of(std::string_view register_name) {
  for (const auto& c : kCodeRegisters)
    if (c.register_name == register_name) return c.codes;
  return {};
}

std::vector<std::pair<std::string, std::span<const Code>>> code_lists() {
  std::vector<std::pair<std::string, std::span<const Code>>> out;
  for (const auto& c : kCodeRegisters) {
    if (!out.empty() && out.back().second.data() == c.codes.data())
      out.back().first += " / " + std::string(c.register_name);  // one list, two registers
    else
      out.emplace_back(std::string(c.register_name), c.codes);
  }
  return out;
}

const Register* find(std::string_view name) {
  for (const auto& r : kTable)
    if (r.name == name) return &r;
  return nullptr;
}

const Register* at(Table t, std::uint16_t address, int* word_index) {
  for (const auto& r : kTable) {
    if (r.table != t) continue;
    const int n = word_count(r.type);
    if (address >= r.address && address < r.address + n) {
      if (word_index) *word_index = address - r.address;
      return &r;
    }
  }
  return nullptr;
}

int word_count(Type type) {
  return type == Type::u32 || type == Type::i32 || type == Type::f32 ? 2 : 1;
}

std::string_view to_string(Table t) {
  switch (t) {
    case Table::coil:
      return "coil";
    case Table::discrete_input:
      return "discrete_input";
    case Table::input_register:
      return "input_register";
    case Table::holding_register:
      return "holding_register";
  }
  return "?";
}
std::string_view to_string(Type t) {
  switch (t) {
    case Type::bit:
      return "bit";
    case Type::u16:
      return "u16";
    case Type::i16:
      return "i16";
    case Type::u32:
      return "u32";
    case Type::i32:
      return "i32";
    case Type::f32:
      return "f32";
  }
  return "?";
}
std::string_view to_string(Access a) { return a == Access::read_only ? "R" : "RW"; }

}  // namespace maglead::registers
