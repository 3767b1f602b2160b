#pragma once
// The kinds of force-driven axis the analysis reads (docs/analysis.md, a rotary axis): which
// recording columns hold the motion and the drive, and what the effect units' parameters are
// called in the kind's units. The units' laws are written for a nut along p in metres and a
// force in newtons; a rotary axis runs the same laws on an angle in radians and a torque in
// newton metres (M p̈ + C ṗ + F_c sign ṗ = F reads J θ̈ + b θ̇ + c sign θ̇ = τ), so only the
// names and units change. This is the one place that choice is made.
#include <string>
#include <string_view>
#include <vector>

namespace maglead::effects {

class Effect;

struct AxisKind {
  std::string_view name;                    // the recording's `# axis:` value ("linear", "rotary")
  std::string_view system;                  // the model file's [model] system ("axis", "rotary")
  std::string_view position;                // the measured position column
  std::string_view drive;                   // the measured drive force (torque) column
  std::string_view drive_unit;              // "N", "N·m"
  std::string_view quantity;                // "force", "torque": what the drive gives, in words
  std::string_view motion;                  // "position", "angle": what the position is, in words
  std::string_view map_unit;                // the residual maps' position unit ("mm", "rad") …
  std::string_view map_rate_unit;           // … and velocity unit ("mm/s", "rad/s") …
  double map_scale = 1.0;                   // … the SI value times this
  std::vector<std::string_view> setpoints;  // columns whose steps are input edges, first found
  // Effect units whose law or range is stated in a lead screw's lengths and speeds only (a
  // ripple period scanned in millimetres): not offered on this kind until restated.
  std::vector<std::string> not_offered;

  /// A unit's parameter name (`viscous_n_s_per_m`) as this kind calls it
  /// (`viscous_n_m_s_per_rad`); the linear kind keeps every name.
  std::string name_of(std::string_view unit_name) const;
  /// The unit's name of a name of this kind (the inverse of name_of over the library's
  /// parameters); empty when no unit has it.
  std::string unit_name_of(std::string_view kind_name) const;
  /// A text of the library or the analysis, written for the nut along p (a law, a parameter's
  /// meaning, "the force"), in this kind's words: on a shaft a force is a torque, F is τ, v is
  /// ω, p is θ, M is J (whole words and symbols only; `nut_mass_kg` stays). The linear kind keeps
  /// the text; this is the one place such words change.
  std::string words(std::string_view linear_text) const;
  /// A unit's law on this kind of axis (Effect::axis_law: no load cell), in the kind's words.
  /// The actuator, which has a load cell, reads Effect::law itself.
  std::string law(const Effect& e) const;
};

const AxisKind& linear_axis();
const AxisKind& rotary_axis();
/// The kind a recording's `# axis:` value names (none: linear); nullptr when unknown.
const AxisKind* axis_kind(std::string_view name);
/// The kind a model file's system names ("axis": linear, "rotary"); nullptr otherwise.
const AxisKind* axis_kind_of_system(std::string_view system);
/// The unit a system's forces are in: a rotary axis's torques in N·m, every other's in N.
std::string_view drive_unit_of_system(std::string_view system);

}  // namespace maglead::effects
