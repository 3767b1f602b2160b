// The axis path on a rotary axis (docs/analysis.md, a rotary axis): a generated servo drive
// (rotary_drive.hpp: angle in rad, torque in N·m) analysed with a baseline that lacks one
// friction term. The analysis names it in the rotary's units, within two standard errors and a
// few per cent of the truth, names nothing else, and a recording whose header or columns do not
// say rotary gets an error that says what to type.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <set>
#include <string>
#include <utility>

#include "maglead/analysis/analysis.hpp"
#include "maglead/physics/force_model.hpp"
#include "rotary_drive.hpp"

namespace {

using maglead::analysis::AnalysisResult;
using maglead::analysis::ModelFile;
using maglead::analysis::parameter_value;
using maglead::test::RotaryDrive;

// A bias the whole recording shares is not in the jackknife's error (docs/analysis.md, how to
// read a finding): the filter and the decimation's few per cent on a viscous coefficient.
constexpr double kBiasShare = 0.04;

ModelFile rotary_model(std::set<std::string> fit) {
  ModelFile m;
  m.system = "rotary";
  m.nut_mass_kg = m.viscous_n_s_per_m = m.coulomb_n = 0.0;  // the units' names, in SI: J, b, c
  m.fit = std::move(fit);
  return m;
}

AnalysisResult analyze(const maglead::Recording& rec, const ModelFile& model) {
  return maglead::analysis::analyze_recording(rec, model, maglead::paper_calibration(),
                                              maglead::ActuatorParams{}, {});
}

std::string named(const AnalysisResult& r) {
  std::string s = r.headline;
  for (const auto& e : r.findings.effects) s += "\n  " + e.id + ": " + e.summary;
  for (const auto& ev : r.findings.events)
    s += "\n  event " + ev.type + " at " + std::to_string(ev.t_s) + " s";
  return s;
}

// The one finding `id` with its parameter `name` near `truth`: within 2 standard errors and
// kBiasShare of it.
void expect_found(const AnalysisResult& r, const std::string& id, const std::string& name,
                  double truth) {
  ASSERT_EQ(r.findings.effects.size(), 1u) << named(r);
  const auto& e = r.findings.effects[0];
  EXPECT_EQ(e.id, id) << named(r);
  const double v = parameter_value(e.parameters, name, NAN);
  const double se = parameter_value(e.standard_errors, name, NAN);
  ASSERT_TRUE(std::isfinite(v) && std::isfinite(se)) << named(r);
  EXPECT_LE(std::abs(v - truth), 2 * se + kBiasShare * truth) << named(r);
  EXPECT_TRUE(r.findings.events.empty()) << named(r);
  std::printf("rotary: %s (true %s %g)\n", r.headline.c_str(), name.c_str(), truth);
}

TEST(Rotary, MissingViscousFrictionIsNamedInRotaryUnits) {
  const RotaryDrive d;
  const auto r =
      analyze(maglead::test::rotary_recording(d), rotary_model({"nut_mass_kg", "coulomb_n"}));
  expect_found(r, "viscous_friction", "viscous_n_m_s_per_rad", d.viscous_n_m_s_per_rad);
  EXPECT_NE(r.headline.find("viscous_n_m_s_per_rad"), std::string::npos) << r.headline;
  EXPECT_NE(r.headline.find("N·m·s/rad (model 0 N·m·s/rad)"), std::string::npos) << r.headline;
  // The baseline's fitted totals carry the rotary's names and units too.
  const auto& base = r.findings.final_fit.fitted_parameters.value();
  EXPECT_NEAR(parameter_value(base, "inertia_kg_m2", NAN), d.inertia_kg_m2,
              kBiasShare * d.inertia_kg_m2)
      << r.findings.final_fit.summary;
  EXPECT_NEAR(parameter_value(base, "coulomb_n_m", NAN), d.coulomb_n_m, kBiasShare * d.coulomb_n_m)
      << r.findings.final_fit.summary;
  // The corrected model holds the values it found: analysed with it, nothing is missing.
  EXPECT_NEAR(r.corrected.viscous_n_s_per_m, d.viscous_n_m_s_per_rad,
              kBiasShare * d.viscous_n_m_s_per_rad + 1e-4);
  EXPECT_EQ(r.corrected.system, "rotary");
  const auto again = analyze(maglead::test::rotary_recording(d), r.corrected);
  EXPECT_TRUE(again.findings.effects.empty()) << named(again);
}

TEST(Rotary, MissingCoulombFrictionIsNamedInRotaryUnits) {
  RotaryDrive d;
  d.seed = 2;
  const auto r = analyze(maglead::test::rotary_recording(d),
                         rotary_model({"nut_mass_kg", "viscous_n_s_per_m"}));
  expect_found(r, "coulomb_friction", "coulomb_n_m", d.coulomb_n_m);
  EXPECT_NE(r.headline.find(" N·m (model 0 N·m)"), std::string::npos) << r.headline;
}

TEST(Rotary, AHeaderOrColumnsThatDoNotSayRotaryAreAClearError) {
  const RotaryDrive d;
  const ModelFile model = rotary_model({"nut_mass_kg", "coulomb_n"});
  const auto message = [&](const maglead::Recording& rec, const ModelFile& m) -> std::string {
    try {
      analyze(rec, m);
    } catch (const std::exception& e) {
      return e.what();
    }
    return "no error";
  };
  // The header line missing: says to add it.
  const std::string no_header = message(maglead::test::rotary_recording(d, false), model);
  EXPECT_NE(no_header.find("add the header line '# axis: rotary'"), std::string::npos) << no_header;
  // A rotary header on a linear axis's columns: says which columns a rotary axis needs.
  auto linear_columns = maglead::test::rotary_recording(d);
  linear_columns.names = {"t_s", "pos_m", "drive_force_n", "ref_pos_m"};
  const std::string wrong = message(linear_columns, model);
  EXPECT_NE(wrong.find("a rotary axis needs the columns t_s, angle_rad, drive_torque_n_m"),
            std::string::npos)
      << wrong;
  EXPECT_NE(wrong.find("remove the header line '# axis: rotary'"), std::string::npos) << wrong;
  // A rotary recording with a linear model: says which model it needs.
  ModelFile linear = model;
  linear.system = "axis";
  const std::string mixed = message(maglead::test::rotary_recording(d), linear);
  EXPECT_NE(mixed.find("give a rotary model"), std::string::npos) << mixed;
  // An angle of thousands of radians is an angle, not a length: the unit checks pass it.
  EXPECT_NO_THROW(maglead::check_plausible_units(maglead::test::rotary_recording(d)));
}

}  // namespace
