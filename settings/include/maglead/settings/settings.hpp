#pragma once
// The one place that reads configuration files (config/*.toml and a calibration) into the plain
// structs the core libraries take. Nothing below this library touches the filesystem for its
// configuration: a test or a new backend builds the structs without files. Every reader throws
// std::runtime_error "FILE:LINE:COLUMN: what" on a bad value or an unknown key; absent keys keep
// their defaults. (The model file has its own reader and writer, twin/model.hpp: it is data the
// analysis writes, not configuration.)
#include <string>

#include "maglead/canopen/cia402_hardware.hpp"
#include "maglead/controller/controller.hpp"
#include "maglead/modbus/network_config.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/twin/model.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead {

/// The [actuator] table of a TOML file.
ActuatorParams load_actuator_params(const std::string& path);

/// TOML round trip of a calibration ([calibration] table); written atomically.
void save_calibration(const std::string& path, const ForceCalibration& cal,
                      const std::string& header_comment = "");
ForceCalibration load_calibration(const std::string& path);

}  // namespace maglead

namespace maglead::modbus {

/// Reads [tcp], [rtu], [server], [fault_reaction] and [runtime] of config/network.toml.
NetworkConfig load_network_config(const std::string& path);
/// "mode_default", "release", "hold" or "disable"; nothing otherwise.
std::optional<controller::FaultReaction> parse_fault_reaction(std::string_view text);

}  // namespace maglead::modbus

namespace maglead::canopen {

/// Reads the [drive] table of `path` (config/drive.toml) over `base`: absent keys keep base's
/// values; what needs more than one key is checked at the table (check_drive_config).
DriveConfig load_drive_config(const std::string& path, DriveConfig base);

}  // namespace maglead::canopen

namespace maglead::twin {

/// The twin's monitor from a configuration folder: its actuator.toml, calibration.toml (else the
/// paper's) and model.toml, where they exist.
TwinMonitorConfig load_monitor_config(const std::string& config_dir);

}  // namespace maglead::twin

namespace maglead::settings {

/// CONFIG_DIR/NAME.
std::string config_file(const std::string& config_dir, const std::string& name);
/// Loads CONFIG/actuator.toml (defaults when the file is absent).
ActuatorParams load_actuator_or_default(const std::string& config_dir);
/// The [control] table of CONFIG/actuator.toml into the controller's settings: when "reached"
/// holds, and the force loop's and the load observer's settings (docs/force-control.md). Absent
/// keys (or no file) keep the values given.
void load_control_settings(const std::string& config_dir, controller::ControllerConfig& cfg);
/// The controller's settings as `serve` runs them: the actuator, the calibration (CONFIG's or the
/// file given), [control], [reference_move], and the model file's terms (CONFIG/model.toml or
/// the file given, when it exists; else the actuator's friction). `model_used` gets the model
/// file read, empty when none.
controller::ControllerConfig controller_config_of(const std::string& config_dir,
                                                  const std::string& calibration,
                                                  const std::string& model,
                                                  std::string* model_used);
/// The model file's terms the controller compensates with: its friction, offset and mass
/// (twin::friction_model), its coupling's gain, ripple and end effect (the twin applies the rest
/// itself).
void serve_model_terms(const twin::TwinModel& model, controller::ControllerConfig& cfg);
/// The [reference_move] table of CONFIG/actuator.toml (mode_command 3): the window inside the
/// actuator's stroke, the two speeds (slow below fast) and the acceleration. A bad value leaves
/// `move` unchanged.
void load_reference_move(const std::string& config_dir, const ActuatorParams& actuator,
                         controller::ReferenceMoveConfig& move);
/// load_control_settings and load_reference_move on the actuator file `path`:
/// load_actuator_params checks both tables with them, so that every command reading the file
/// refuses what serve refuses.
void read_control_section(const std::string& path, controller::ControllerConfig& cfg);
void read_reference_move_section(const std::string& path, const ActuatorParams& actuator,
                                 controller::ReferenceMoveConfig& move);

}  // namespace maglead::settings
