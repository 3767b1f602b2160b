#pragma once
// The analysis reads and writes the one model file of maglead (twin/model.hpp).
#include <string>

#include "maglead/physics/actuator.hpp"
#include "maglead/twin/model.hpp"

namespace maglead::analysis {

using ModelTerm = twin::ModelTerm;
using ModelFile = twin::TwinModel;

inline ModelFile load_model(const std::string& path) { return twin::load_twin_model(path); }
inline void save_model(const std::string& path, const ModelFile& model, const std::string& header) {
  twin::save_twin_model(path, model, header);
}

/// Actuator baseline from config/actuator.toml: mass, viscous and Coulomb friction.
ModelFile actuator_model_from_config(const ActuatorParams& act);

}  // namespace maglead::analysis
