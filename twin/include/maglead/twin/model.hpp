#pragma once
// The model file: the one model vocabulary of maglead. The twin runs it, `maglead analyze`
// compares it with recordings and writes corrected ones in the same form, so a corrected model
// is loaded by the twin (and by the analysis again) without translation.
//
//   # format: maglead-model/1          # required first line (check_model_format)
//   [model]
//   source = "paper defaults"          # free text: where the numbers came from
//   nut_mass_kg = 0.12                 # M
//   viscous_n_s_per_m = 2.0            # C
//   coulomb_n = 7.5                    # F_c (kinetic and break-away unless a term says more)
//
//   [[term]]                           # zero or more: one effect of the effect library
//   id = "offset"                      # an id of docs/effects.md
//   enabled = true                     # optional, default true
//   note = "found by maglead analyze"  # optional free text
//   offset_n = -3.5                    # the effect's parameters, names and units as in the spec
//
// Two additions for systems that are not the actuator (the EMPS axis), which the twin never
// runs: `system = "axis"` and `fit = ["nut_mass_kg", …]` naming values fitted from the data.
// Unknown ids or parameters are errors: a typo must not silently drop physics.
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "maglead/physics/force_model.hpp"
#include "maglead/physics/friction_model.hpp"

namespace maglead::twin {

struct ModelTerm {
  std::string id;
  bool enabled = true;
  std::string note;
  std::vector<std::pair<std::string, double>> parameters;  // in file order
  /// Value of a parameter, or `fallback` if absent.
  double get(const std::string& name, double fallback) const;
  void set(const std::string& name, double value);
};

struct TwinModel {
  std::string system = "actuator";  // "actuator" (magnetic lead screw) or "axis" (force-driven)
  std::string source = "paper defaults";
  double nut_mass_kg = 0.12;
  double viscous_n_s_per_m = 2.0;
  double coulomb_n = 7.5;
  std::set<std::string> fit;  // [model] keys whose values are unknown (fitted by the analysis)
  std::vector<ModelTerm> terms;

  const ModelTerm* find(const std::string& id) const;  // enabled terms only
  ModelTerm& term(const std::string& id);              // finds or appends
};

inline constexpr const char* kModelFormatLine = "# format: maglead-model/1";
/// Throws std::runtime_error "FILE:1:1: ..." unless the file's first line is kModelFormatLine.
void check_model_format(const std::string& path);
/// Throws std::runtime_error naming the file, line and column, and the term and key at fault.
TwinModel load_twin_model(const std::string& path);
/// Writes the format above; throws std::runtime_error on I/O error or an invalid model.
void save_twin_model(const std::string& path, const TwinModel& model,
                     const std::string& header_comment = "");
/// Validates values, ids and parameter names against the effect library; throws
/// std::invalid_argument naming the term and parameter.
void validate_twin_model(const TwinModel& model);
/// The friction, offset and mass the controller's force loop and load observer compensate
/// with: [model] M, C, F_c and the enabled coulomb_friction, viscous_friction,
/// asymmetric_friction, stribeck_friction, offset and mass_error terms (docs/effects.md).
FrictionModel friction_model(const TwinModel& model);
/// The coupling the model states beyond the calibration: its gain (coupling_gain_error, 1
/// without it), its ripple over the screw's turn (angle_ripple) and its end effect.
CouplingModel coupling_model(const TwinModel& model);

}  // namespace maglead::twin
