// libFuzzer target: the TOML readers of outside files: config/actuator.toml
// (load_actuator_params), calibration.toml (load_calibration), network.toml
// (load_network_config) and the model file (load_twin_model), all on physics/toml_config.hpp.
//
// Input: [reader][file…]: reader % 4 picks the reader (0 actuator, 1 calibration, 2 network,
// 3 model); the rest is the file.
// Oracles: each reader returns or throws a std::exception whose message names the file and says
// why (no crash, no hang); what it returns keeps its documented promises: actuator values
// positive with stroke_min_m < stroke_max_m and safe_force_fraction ≤ 1; a calibration's
// coefficients finite, its push peak > 0 and pull peak < 0; a model file written back by
// save_twin_model reads back the same.
#include <cmath>

#include "fuzz_common.hpp"
#include "maglead/modbus/network_config.hpp"
#include "maglead/physics/actuator.hpp"
#include "maglead/physics/force_model.hpp"
#include "maglead/settings/settings.hpp"
#include "maglead/twin/model.hpp"

namespace {

constexpr std::string_view kTarget = "fuzz_config";

void check(bool cond, std::string_view what) {
  if (!cond) maglead::fuzz::oracle_failed(kTarget, what);
}

void check_actuator(const maglead::ActuatorParams& a) {
  for (const double v :
       {a.lead_m, a.gear_ratio, a.motor_counts_per_rev, a.linear_count_m, a.nut_mass_kg,
        a.viscous_n_s_per_m, a.coulomb_n, a.stroke_max_m, a.sample_rate_hz, a.safe_force_fraction})
    check(v > 0 && std::isfinite(v), "an actuator value not a positive number");
  check(a.stroke_min_m < a.stroke_max_m, "stroke_min_m not below stroke_max_m");
  check(a.safe_force_fraction <= 1.0, "safe_force_fraction above 1");
  check(a.lead_m <= 1.0 && a.linear_count_m <= 1e-3 && std::abs(a.stroke_min_m) <= 10.0 &&
            std::abs(a.stroke_max_m) <= 10.0,
        "a length beyond what metres can be (lead, count or stroke)");
}

void check_calibration(const maglead::ForceCalibration& c) {
  bool finite = std::isfinite(c.periodic.mean_n);
  for (const auto* values : {&c.polynomial.coeffs_ascending, &c.periodic.cos_n, &c.periodic.sin_n})
    for (const double v : *values) finite = finite && std::isfinite(v);
  check(finite, "a calibration coefficient not finite");
  check(c.peak_push_n > 0 && std::isfinite(c.peak_push_n) && c.peak_pull_n < 0 &&
            std::isfinite(c.peak_pull_n),
        "a calibration without a finite push (> 0) and pull (< 0) peak");
}

bool same_model(const maglead::twin::TwinModel& a, const maglead::twin::TwinModel& b) {
  if (a.system != b.system || a.source != b.source || a.nut_mass_kg != b.nut_mass_kg ||
      a.viscous_n_s_per_m != b.viscous_n_s_per_m || a.coulomb_n != b.coulomb_n || a.fit != b.fit ||
      a.terms.size() != b.terms.size())
    return false;
  for (std::size_t i = 0; i < a.terms.size(); ++i) {
    const auto &x = a.terms[i], &y = b.terms[i];
    if (x.id != y.id || x.enabled != y.enabled || x.note != y.note || x.parameters != y.parameters)
      return false;
  }
  return true;
}

void check_model_round_trip(const maglead::twin::TwinModel& m, const std::string& path) {
  const std::string copy = path + ".saved.toml";
  try {
    maglead::twin::save_twin_model(copy, m);
  } catch (const std::exception& e) {
    maglead::fuzz::oracle_failed(kTarget,
                                 std::string("a loaded model cannot be saved: ") + e.what());
  }
  try {
    check(same_model(m, maglead::twin::load_twin_model(copy)), "a saved model reads back changed");
  } catch (const std::exception& e) {
    maglead::fuzz::oracle_failed(kTarget, std::string("a saved model cannot be read: ") + e.what());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const int reader = data[0] % 4;
  const std::string path = maglead::fuzz::write_input(data + 1, size - 1, ".toml");
  try {
    switch (reader) {
      case 0:
        check_actuator(maglead::load_actuator_params(path));
        break;
      case 1:
        check_calibration(maglead::load_calibration(path));
        break;
      case 2:
        (void)maglead::modbus::load_network_config(path);
        break;
      default:
        check_model_round_trip(maglead::twin::load_twin_model(path), path);
    }
  } catch (const std::exception& e) {
    maglead::fuzz::check_refusal(kTarget, e, path);
  }
  return 0;
}
