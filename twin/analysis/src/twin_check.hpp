#pragma once
// Internal: re-simulation of baseline and corrected twins over short horizons from measured
// states (the secondary check; the force-domain fit is the primary one).
#include <vector>

#include "maglead/analysis/model_file.hpp"
#include "maglead/analysis/results.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"

namespace maglead::analysis {

struct TwinCheckInput {
  const std::vector<double>& t;
  const std::vector<double>& p;      // filtered nut position
  const std::vector<double>& v;      // its velocity
  const std::vector<double>& theta;  // filtered screw angle
  const std::vector<double>& load;   // measured load force (filtered)
  ActuatorParams act;
  PeriodicForceModel coupling;
  double fs_hz = 1000.0;
  double horizon_s = 0.1;
};

TwinSimulation simulate_twins(const TwinCheckInput& in, const ModelFile& baseline,
                              const ModelFile& corrected);

}  // namespace maglead::analysis
