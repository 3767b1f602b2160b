#include <cmath>
#include <stdexcept>

#include "maglead/plant/simulated_actuator.hpp"

namespace maglead {
namespace {

struct EffectEntry {
  const char* name;
  double PlantEffects::*field;
  const char* help;
};

constexpr EffectEntry kEffects[] = {
    {"viscous_friction", &PlantEffects::viscous_friction_n_s_per_m, "N·s/m  extra viscous friction"},
    {"stribeck_friction", &PlantEffects::stribeck_friction_n, "N  break-away excess over Coulomb (Stribeck velocity 2 mm/s)"},
    {"asymmetric_friction", &PlantEffects::asymmetric_friction_n, "N  Coulomb friction +value moving +p, −value moving −p"},
    {"offset", &PlantEffects::offset_n, "N  constant force on the nut along +p (gravity, a constant load)"},
    {"gain_drift", &PlantEffects::gain_drift_per_min, "1/min  relative change of magnet coupling per minute (−0.05: −5 %/min)"},
    {"angle_ripple", &PlantEffects::angle_ripple_n, "N  force ripple once per screw turn (eccentricity), amplitude"},
    {"position_ripple", &PlantEffects::position_ripple_n, "N  force ripple fixed to nut position, 5 mm period, amplitude"},
    {"backlash", &PlantEffects::backlash_rad, "rad  gearbox play at the screw"},
    {"end_effect", &PlantEffects::end_effect_m, "m  coupling weakens (to 50 %) within this distance of a stroke end"},
    {"load_cell_delay", &PlantEffects::load_cell_delay_s, "s  load-cell signal delay"},
    {"sensor_delay", &PlantEffects::sensor_delay_s, "s  linear-encoder signal delay"},
    {"spring", &PlantEffects::spring_n_per_m, "N/m  spring pulling the nut towards mid-stroke"},
    {"mass_error", &PlantEffects::mass_error_kg, "kg  moving mass beyond the nominal"},
    {"external_disturbance", &PlantEffects::external_disturbance_n, "N  50 ms force pulses at random times, amplitude"},
};

}  // namespace

void set_plant_effect(PlantEffects& effects, const std::string& name, double value) {
  if (!std::isfinite(value))
    throw std::invalid_argument("effect '" + name + "': value must be a finite number");
  for (const auto& e : kEffects) {
    if (name == e.name) {
      const bool must_be_positive = name == "backlash" || name == "end_effect" ||
                                    name == "load_cell_delay" || name == "sensor_delay" ||
                                    name == "stribeck_friction";
      if (must_be_positive && value < 0.0)
        throw std::invalid_argument("effect '" + name + "': value must not be negative");
      effects.*(e.field) = value;
      return;
    }
  }
  std::string known;
  for (const auto& e : kEffects) known += (known.empty() ? "" : ", ") + std::string(e.name);
  throw std::invalid_argument("unknown effect '" + name + "' (known: " + known + ")");
}

std::vector<std::pair<std::string, std::string>> plant_effect_help() {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& e : kEffects) out.emplace_back(e.name, e.help);
  return out;
}

}  // namespace maglead
