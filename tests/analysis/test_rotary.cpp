// The axis path on a rotary axis (docs/analysis.md, a rotary axis): a generated servo drive
// (rotary_drive.hpp: angle in rad, torque in N·m) analysed with a baseline that lacks one
// friction term. The analysis names it in the rotary's units, within two standard errors and a
// few per cent of the truth, names nothing else, and a recording whose header or columns do not
// say rotary gets an error that says what to type.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/reading.hpp"
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
  EXPECT_LE(std::abs(v - truth), 2 * se + kBiasShare * std::abs(truth)) << named(r);
  // No event names a disturbance (a misfit window is where the residual is larger, not a claim).
  for (const auto& ev : r.findings.events) EXPECT_NE(ev.type, "external_disturbance") << named(r);
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
  // Nor a misfit: the filters' edges at the recording's ends are no torque the model leaves out.
  EXPECT_TRUE(again.headline.starts_with("nothing missing")) << again.headline;
}

// A logger at 100 Hz: the position filter's corner follows its rate (a fifth of it, as on the
// actuator), never the 100 Hz default beyond its Nyquist frequency.
TEST(Rotary, ASlowLoggerIsAnalysedWithTheFilterBelowItsNyquist) {
  const RotaryDrive d;
  auto rec = maglead::test::rotary_recording(d);
  constexpr std::size_t kEvery = 10;
  for (auto& column : rec.columns) {
    std::vector<double> kept;
    for (std::size_t i = 0; i < column.size(); i += kEvery) kept.push_back(column[i]);
    column = std::move(kept);
  }
  rec.set_meta("sample_rate_hz", "100");
  const auto r = analyze(rec, rotary_model({"nut_mass_kg", "coulomb_n"}));
  EXPECT_NE(r.findings.method.filter.find("angle at 20 Hz"), std::string::npos)
      << r.findings.method.filter;
  expect_found(r, "viscous_friction", "viscous_n_m_s_per_rad", d.viscous_n_m_s_per_rad);
  // Below axis_min_rate_hz (here t_s as if in milliseconds: 0.1 Hz) it is refused, saying why.
  for (double& t : rec.columns[0]) t *= 1e3;
  rec.set_meta("sample_rate_hz", "0.1");
  try {
    (void)analyze(rec, rotary_model({"nut_mass_kg", "coulomb_n"}));
    ADD_FAILURE() << "a 0.1 Hz axis recording was analysed";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("if t_s is in milliseconds, divide it by 1000"),
              std::string::npos)
        << e.what();
  }
}

// Moves with stops between them, the PD holding the shaft against stiction with whatever torque
// up to c it settled at: the holds are left out of the fit (and said so), so no hold is an
// event, and the viscous friction the baseline lacks is still named within its error.
TEST(Rotary, AShaftHeldBetweenMovesIsNoEvent) {
  RotaryDrive d;
  d.dwell_s = 1.0;
  const auto r =
      analyze(maglead::test::rotary_recording(d), rotary_model({"nut_mass_kg", "coulomb_n"}));
  bool said = false;
  for (const auto& w : r.where) said |= w.rfind("held still ", 0) == 0;
  EXPECT_TRUE(said) << "the holds are not said; where: " << r.where.size() << " lines";
  expect_found(r, "viscous_friction", "viscous_n_m_s_per_rad", d.viscous_n_m_s_per_rad);
  for (const auto& w : r.where)
    if (w.rfind("held still ", 0) == 0) std::printf("rotary with stops: %s\n", w.c_str());
}

// A Coulomb friction strong enough to stick the shaft for a few milliseconds at reversals (the
// drive's torque passes through ±c slower than a hold takes to show): a model with every term
// explains the recording, and those sticks are the friction the model holds, not disturbances.
TEST(Rotary, ABriefStickAtAReversalIsNoDisturbance) {
  RotaryDrive d;
  d.coulomb_n_m = 0.4;
  d.viscous_n_m_s_per_rad = 0.0;
  for (const unsigned seed : {1u, 2u, 3u}) {
    d.seed = seed;
    const auto r = analyze(maglead::test::rotary_recording(d),
                           rotary_model({"nut_mass_kg", "coulomb_n", "viscous_n_s_per_m"}));
    EXPECT_TRUE(r.findings.effects.empty()) << "seed " << seed << ": " << named(r);
    std::printf("rotary, c = 0.4 N·m, seed %u: %s\n", seed, r.headline.c_str());
  }
}

TEST(Rotary, MissingCoulombFrictionIsNamedInRotaryUnits) {
  RotaryDrive d;
  d.seed = 2;
  const auto r = analyze(maglead::test::rotary_recording(d),
                         rotary_model({"nut_mass_kg", "viscous_n_s_per_m"}));
  expect_found(r, "coulomb_friction", "coulomb_n_m", d.coulomb_n_m);
  EXPECT_NE(r.headline.find(" N·m (model 0 N·m)"), std::string::npos) << r.headline;
}

// A constant load torque (an unbalanced arm held level would be one) beside a model whose J, b
// and c are all fitted: named as an offset in N·m.
TEST(Rotary, ALoadTorqueIsAnOffsetInNewtonMetres) {
  RotaryDrive d;
  d.offset_n_m = 0.03;
  d.seed = 3;
  const auto r = analyze(maglead::test::rotary_recording(d),
                         rotary_model({"nut_mass_kg", "viscous_n_s_per_m", "coulomb_n"}));
  // The drive supplies the load torque: the offset the axis names is the torque the drive adds,
  // the load's with its sign turned.
  expect_found(r, "offset", "offset_n_m", -d.offset_n_m);
  // A servo has no load cell: the law its finding quotes (and model_corrected.toml's note with
  // it) says none; the actuator's offset is unseen by its load cell.
  ASSERT_FALSE(r.findings.effects.empty());
  EXPECT_EQ(r.findings.effects[0].where,
            "all samples; the missing torque follows τ = τ_o (constant, along +θ)");
}

// A torque pulse no input explains (a knock on the arm): the event's finding speaks of torque
// pulses, in the axis kind's words as every other text of a rotary axis.
TEST(Rotary, ATorquePulseIsSaidInTorque) {
  RotaryDrive d;
  auto rec = maglead::test::rotary_recording(d);
  auto& torque = rec.columns[2];
  // 50 ms: the drive is identified at 50 Hz (20 ms a step), and a pulse of barely one and a half
  // steps is sampled too coarsely to tell its one sign from the filter's swing.
  for (std::size_t i = torque.size() / 2; i < torque.size() / 2 + 50; ++i) torque[i] += 0.4;
  const auto r = analyze(rec, rotary_model({"nut_mass_kg", "coulomb_n"}));
  const auto pulse = std::find_if(r.findings.effects.begin(), r.findings.effects.end(),
                                  [](const auto& e) { return e.id == "external_disturbance"; });
  ASSERT_NE(pulse, r.findings.effects.end()) << named(r);
  EXPECT_EQ(pulse->where, "isolated torque pulses no input explains (see events)");
}

// The model file of a rotary axis names its values and its terms' parameters in rotary units,
// and reads them back as the units' own.
TEST(Rotary, TheModelFileCarriesRotaryNames) {
  ModelFile m = rotary_model({"nut_mass_kg"});
  m.viscous_n_s_per_m = 2e-3;
  m.term("offset").set("offset_n", -0.03);
  const std::string path = ::testing::TempDir() + "rotary_model.toml";
  maglead::analysis::save_model(path, m, "");
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const char* key :
       {"system = \"rotary\"", "inertia_kg_m2 = 0", "viscous_n_m_s_per_rad = 0.002",
        "coulomb_n_m = 0", "fit = [\"inertia_kg_m2\"]", "offset_n_m = -0.0"})
    EXPECT_NE(text.find(key), std::string::npos) << key << " in\n" << text;
  const ModelFile back = maglead::analysis::load_model(path);
  EXPECT_EQ(back.fit, m.fit);
  EXPECT_DOUBLE_EQ(back.viscous_n_s_per_m, 2e-3);
  ASSERT_NE(back.find("offset"), nullptr);
  EXPECT_DOUBLE_EQ(back.find("offset")->get("offset_n", 0.0), -0.03);
  // A linear name in a rotary model is a typo the error names with the rotary's.
  std::ofstream(path) << "# format: maglead-model/1\n[model]\nsystem = \"rotary\"\n"
                         "viscous_n_s_per_m = 0.002\n";
  try {
    maglead::analysis::load_model(path);
    ADD_FAILURE() << "a linear name was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("viscous_n_m_s_per_rad"), std::string::npos) << e.what();
  }
}

// A torque logged with the wrong sign is a missing torque no library law explains plausibly:
// said so with the rotary's names and columns (Axis.AForceOfTheWrongSignIsNotExplainedPlausibly
// on a linear axis).
TEST(Rotary, ATorqueOfTheWrongSignIsNotExplainedPlausibly) {
  const RotaryDrive d;
  const auto rec = maglead::test::rotary_recording(d);
  const auto first = analyze(rec, rotary_model({"nut_mass_kg", "viscous_n_s_per_m", "coulomb_n"}));
  auto flipped = rec;
  for (double& tau : flipped.columns[2]) tau = -tau;
  const auto r = analyze(flipped, first.corrected);
  EXPECT_TRUE(r.findings.effects.empty()) << named(r);
  ASSERT_TRUE(r.findings.unexplained.has_value()) << r.findings.conclusion;
  const auto& u = *r.findings.unexplained;
  EXPECT_NE(u.check.find("sign of drive_torque_n_m and angle_rad"), std::string::npos) << u.check;
  for (const auto& p : u.parameters)
    EXPECT_NE(u.message.find(" " + p.name + " = "), std::string::npos) << u.message;
  EXPECT_EQ(u.message.find("_n_s_per_m"), std::string::npos) << u.message;
  EXPECT_EQ(u.message.find("nut_mass_kg"), std::string::npos) << u.message;
  std::printf("rotary, torque of the wrong sign: %s\n", u.message.c_str());
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
  // A rotary recording with the actuator's model (no --model): says which model it needs.
  ModelFile actuator = model;
  actuator.system = "actuator";
  const std::string no_model = message(maglead::test::rotary_recording(d), actuator);
  EXPECT_NE(no_model.find("give the axis's baseline with --model"), std::string::npos) << no_model;
  // An angle of thousands of radians is an angle, not a length: the unit checks pass it.
  EXPECT_NO_THROW(maglead::check_plausible_units(maglead::test::rotary_recording(d)));
}

// When header and model disagree, the columns the file has decide the fix: a linear axis's
// columns with a rotary model want a linear model, not a header line; a rotary header on a linear
// axis's columns, analysed with a linear model, wants the header line removed, not a rotary model.
TEST(Rotary, AMismatchIsFixedTowardsTheColumnsTheFileHas) {
  const RotaryDrive d;
  const auto message = [](const maglead::Recording& rec, const ModelFile& m) -> std::string {
    try {
      analyze(rec, m);
    } catch (const std::exception& e) {
      return e.what();
    }
    return "no error";
  };
  auto linear_columns = maglead::test::rotary_recording(d, false);
  linear_columns.names = {"t_s", "pos_m", "drive_force_n", "ref_pos_m"};
  ModelFile linear = rotary_model({"nut_mass_kg", "coulomb_n"});
  linear.system = "axis";
  const std::string rotary_model_on_linear =
      message(linear_columns, rotary_model({"nut_mass_kg", "coulomb_n"}));
  EXPECT_NE(rotary_model_on_linear.find("give a linear axis's model (system = \"axis\""),
            std::string::npos)
      << rotary_model_on_linear;
  EXPECT_EQ(rotary_model_on_linear.find("add the header line"), std::string::npos)
      << rotary_model_on_linear;
  linear_columns.set_meta("axis", "rotary");
  const std::string rotary_header = message(linear_columns, linear);
  EXPECT_NE(rotary_header.find("remove the header line '# axis: rotary'"), std::string::npos)
      << rotary_header;
  EXPECT_EQ(rotary_header.find("give a rotary model"), std::string::npos) << rotary_header;
}

// A rotary file whose angle is in degrees: the message lists the header's columns and says what
// to convert, as a missing column of the actuator's does (recording.cpp, missing_column_detail).
TEST(Rotary, AnAngleInDegreesIsNamedWithWhatToConvert) {
  auto rec = maglead::test::rotary_recording(RotaryDrive{});
  rec.names[1] = "angle_deg";
  std::string e = "no error";
  try {
    analyze(rec, rotary_model({"nut_mass_kg", "coulomb_n"}));
  } catch (const std::exception& x) {
    e = x.what();
  }
  EXPECT_NE(e.find("(header has: t_s, angle_deg, drive_torque_n_m, ref_angle_rad)"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("'angle_deg' looks like angle_rad in another unit: convert it to radians and "
                   "name it 'angle_rad'"),
            std::string::npos)
      << e;
}

// What analyze refuses on a rotary recording says what to fix: a torque in mN·m or a time in
// ms is named with what to convert (as a linear axis's drive_force_kn is), and a header that
// says '# axis: linear' is quoted and changed, not told it has no axis line.
TEST(Rotary, ARefusalSaysWhatToFix) {
  const auto refusal = [](auto edit) {
    auto rec = maglead::test::rotary_recording(RotaryDrive{});
    edit(rec);
    try {
      analyze(rec, rotary_model({"nut_mass_kg", "coulomb_n"}));
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const auto says = [](const std::string& text, const std::string& part) {
    EXPECT_NE(text.find(part), std::string::npos) << text;
  };
  says(refusal([](auto& r) { r.names[2] = "drive_torque_mn_m"; }),
       "'drive_torque_mn_m' looks like drive_torque_n_m in another unit: convert it to newton "
       "metres and name it 'drive_torque_n_m'");
  says(refusal([](auto& r) { r.names[0] = "t_ms"; }),
       "(header has: t_ms, angle_rad, drive_torque_n_m, ref_angle_rad); 't_ms' looks like t_s in "
       "another unit: convert it to seconds and name it 't_s'");
  const std::string linear = refusal([](auto& r) { r.set_meta("axis", "linear"); });
  says(linear,
       "but the header says '# axis: linear': change the header line '# axis: linear' to "
       "'# axis: rotary'");
  EXPECT_EQ(linear.find("no '# axis: rotary' line"), std::string::npos) << linear;
}

}  // namespace

namespace {

// The header's names a reader keeping analysis::columns_read stores.
std::vector<std::string> kept(const std::vector<std::string>& names, const std::string& axis = "") {
  maglead::Recording header;
  header.names = names;
  if (!axis.empty()) header.set_meta("axis", axis);
  const auto read = maglead::analysis::columns_read(header);
  std::vector<std::string> out;
  for (const auto& n : names)
    if (std::find(read.begin(), read.end(), n) != read.end()) out.push_back(n);
  return out;
}

}  // namespace

// `maglead analyze` stores only these columns (an hour at 1 kHz: 29 MB each): the actuator's
// logged extras and a motor angle beside the screw's are left out, an axis keeps its kind's
// setpoints, and the other kind's columns stay for kind_of's hint; a stated axis with neither
// kind's columns keeps them all.
TEST(Rotary, ColumnsReadAreWhatTheAnalysisReads) {
  using V = std::vector<std::string>;
  EXPECT_EQ(kept({"t_s", "motor_angle_rad", "screw_angle_rad", "nut_pos_m", "load_force_n",
                  "out_force_est_n", "pos_set_m", "force_set_n"}),
            (V{"t_s", "screw_angle_rad", "nut_pos_m", "load_force_n", "force_set_n"}));
  EXPECT_EQ(kept({"t_s", "motor_angle_rad", "nut_pos_m", "load_force_n", "pos_set_m"}),
            (V{"t_s", "motor_angle_rad", "nut_pos_m", "load_force_n"}));
  EXPECT_EQ(kept({"t_s", "angle_rad", "drive_torque_n_m", "torque_set_n_m", "ref_angle_rad",
                  "temp_c", "nut_pos_m"},
                 "rotary"),
            (V{"t_s", "angle_rad", "drive_torque_n_m", "torque_set_n_m", "ref_angle_rad"}));
  EXPECT_EQ(kept({"t_s", "pos_m", "drive_force_n", "pos_set_m"}, "rotary"),
            (V{"t_s", "pos_m", "drive_force_n", "pos_set_m"}));
  // Neither kind's columns under '# axis:': all kept, for the refusal to list and to name
  // angle_deg as angle_rad in another unit.
  EXPECT_EQ(kept({"t_s", "angle_deg", "drive_torque_n_m", "ref_angle_rad"}, "rotary"),
            (V{"t_s", "angle_deg", "drive_torque_n_m", "ref_angle_rad"}));
  // No t_s: all kept, for the refusal to list the header and name t_ms.
  EXPECT_EQ(kept({"t_ms", "angle_rad", "drive_torque_n_m", "temp_c"}, "rotary"),
            (V{"t_ms", "angle_rad", "drive_torque_n_m", "temp_c"}));
}
