#pragma once
// The twin's model file (config/model.toml): nut dynamics parameters plus an extensible list of
// named physical terms. The analysis tool (issue 5) writes the same format back after it has
// found missing physics, so the twin loads its corrections without code changes.
//
//   # format: maglead-model/1          # required first line (check_model_format)
//   [model]
//   source = "paper defaults"          # free text: where the numbers came from
//   nut_mass_kg = 0.12                 # M
//   viscous_n_s_per_m = 2.0            # C
//   coulomb_n = 7.5                    # F_c (break-away = sliding level unless stribeck is on)
//
//   [[term]]                           # zero or more; order does not matter
//   id = "asymmetric_friction"         # one of known_terms()
//   enabled = true                     # optional, default true
//   note = "found at reversals"        # optional free text (evidence, fit quality …)
//   n = 0.8                            # parameters: key = number, names carry units
//
// Terms and parameters (force on the nut along +p unless said otherwise):
//   coulomb_friction     n                 extra Coulomb level, adds to coulomb_n
//   viscous_friction     n_s_per_m         extra viscous coefficient, adds to C
//   asymmetric_friction  n                 Coulomb + n moving +p, − n moving −p
//   stribeck_friction    n, velocity_m_s   break-away excess n·exp(−(v/v_s)²) (v_s default 2 mm/s)
//   offset               force_n           constant force (gravity, constant load)
//   spring               n_per_m, center_m force −k (p − center) (center default mid-stroke)
//   mass_error           kg                extra moving mass
//   gain                 factor            coupling strength × factor (1 = calibrated)
//   gain_drift           per_min           coupling strength × (1 + per_min · t/60 s)
//   angle_ripple         n, phase_rad      n·sin(θ + phase), once per screw turn
//   position_ripple      n, period_m, phase_rad   n·sin(2π p / period + phase) (period 5 mm)
//   end_effect           m, depth          coupling × (1 − depth·max(0, 1 − d_end/m)) (depth 0.5)
//   step_out             (none)            always modelled: the coupling is periodic
//   backlash, sensor_delay, external_disturbance
//                        any               accepted and kept, not simulated by the twin
//                                          (unsimulated_terms() lists them for a warning)
// Unknown ids or parameters are errors (a typo must not silently drop physics).
#include <string>
#include <utility>
#include <vector>

namespace maglead::twin {

struct ModelTerm {
  std::string id;
  bool enabled = true;
  std::string note;
  std::vector<std::pair<std::string, double>> parameters;  // in file order
  /// Value of a parameter, or `fallback` if absent.
  double get(const std::string& name, double fallback) const;
};

struct TwinModel {
  std::string source = "paper defaults";
  double nut_mass_kg = 0.12;
  double viscous_n_s_per_m = 2.0;
  double coulomb_n = 7.5;
  std::vector<ModelTerm> terms;

  /// Enabled terms the twin's dynamics do not simulate (accepted for round trips).
  std::vector<std::string> unsimulated_terms() const;
};

struct TermInfo {
  std::string id;
  std::vector<std::string> parameters;  // allowed parameter names
  std::string description;
  bool simulated;
};
const std::vector<TermInfo>& known_terms();

/// The first line every model file carries (the twin's and the analysis tool's).
inline constexpr const char* kModelFormatLine = "# format: maglead-model/1";
/// Throws std::runtime_error "FILE:1:1: ..." unless the file's first line is kModelFormatLine.
void check_model_format(const std::string& path);
/// Throws std::runtime_error naming FILE:LINE:COLUMN, the term and the bad key or value.
TwinModel load_twin_model(const std::string& path);
/// Writes the format above (used by the analysis tool); throws std::runtime_error on I/O error.
void save_twin_model(const std::string& path, const TwinModel& model,
                     const std::string& header_comment = "");
/// Validates ids and parameter names (what load does after parsing); throws std::invalid_argument.
void validate_twin_model(const TwinModel& model);

}  // namespace maglead::twin
