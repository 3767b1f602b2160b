// The effect library: each unit's regressors are its law, linear in the coefficients the
// analysis fits, so a corrected model reproduces the analysis's error exactly; ids and
// parameter names are those of docs/effects.md.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <optional>
#include <random>
#include <sstream>
#include <string>

#include "maglead/effects/effect.hpp"

namespace maglead::effects {
namespace {

State random_state(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  State s;
  s.t_s = 30.0 + 20.0 * u(rng);
  s.p_m = 0.02 + 0.019 * u(rng);
  s.v_m_s = 0.05 * u(rng);
  s.a_m_s2 = 2.0 * u(rng);
  s.theta_rad = 20.0 * u(rng);
  s.phi_rad = 0.8 * u(rng);
  s.phi_rate_rad_s = 3.0 * u(rng);
  s.coupling_n = 40.0 * u(rng);
  s.coupling_slope_n_per_rad = 45.0 + 5.0 * u(rng);
  s.load_n = 20.0 * u(rng);
  s.load_rate_n_s = 200.0 * u(rng);
  return s;
}

// One of a unit's two fitted forms: the nut's (the actuator) or a force-driven axis's.
struct Form {
  int (Effect::*columns)() const;
  void (Effect::*regressors)(double, const State&, double*) const;
  std::optional<Params> (Effect::*parameters)(double, const double*, const State&) const;
};
constexpr Form kNut{&Effect::columns, &Effect::regressors, &Effect::parameters};
constexpr Form kAxis{&Effect::axis_columns, &Effect::axis_regressors, &Effect::axis_parameters};

void expect_law_linear(const Effect& e, const Form& form, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.05, 0.3);  // positive: sign-constrained units
  auto shapes = e.shapes();
  if (shapes.empty()) shapes.push_back(0.0);
  for (double shape : shapes) {
    std::vector<double> c(static_cast<std::size_t>((e.*form.columns)()));
    for (double& x : c) x = u(rng);
    const State model = random_state(rng);
    const auto p = (e.*form.parameters)(shape, c.data(), model);
    ASSERT_TRUE(p.has_value()) << e.id();
    for (int k = 0; k < 20; ++k) {
      State s = random_state(rng);
      s.coulomb_n = model.coulomb_n;
      s.viscous_n_s_per_m = model.viscous_n_s_per_m;
      s.nut_mass_kg = model.nut_mass_kg;
      std::vector<double> x(c.size());
      (e.*form.regressors)(shape, s, x.data());
      double lin = 0;
      for (std::size_t j = 0; j < c.size(); ++j) lin += c[j] * x[j];
      EXPECT_NEAR(e.force_n(*p, s), lin, 1e-9 * (1 + std::abs(lin)))
          << e.id() << " shape " << shape;
    }
  }
}

TEST(Effects, RegressorsAreTheLawLinearInTheFittedCoefficients) {
  std::mt19937 rng(3);
  for (const Effect* e : library())
    if (e->columns() > 0) expect_law_linear(*e, kNut, rng);
}

// The axis form is the same law (force_n), fitted in the columns a drive's force resolves.
TEST(Effects, AxisRegressorsAreTheSameLaw) {
  std::mt19937 rng(4);
  int on_axis = 0;
  for (const Effect* e : library())
    if (e->on_axis() && e->axis_columns() > 0) expect_law_linear(*e, kAxis, rng), ++on_axis;
  EXPECT_GE(on_axis, 7);  // friction (four laws), offset, spring, mass, position ripple
  EXPECT_EQ(find("asymmetric_friction")->axis_columns(), 4);
  EXPECT_FALSE(find("coupling_gain_error")->on_axis());
  EXPECT_FALSE(find("load_cell_delay")->on_axis());
}

// The analysis asks a unit for its row in a buffer of kMaxColumns: a unit with more is refused
// by name when the library is built, not written past the buffer's end at the first sample.
struct Wide final : Effect {
  explicit Wide(int n) : n_(n) {}
  std::string_view id() const override { return "wide"; }
  std::string_view law() const override { return "a law in many columns"; }
  std::vector<ParamSpec> params() const override { return {}; }
  double force_n(const Params&, const State&) const override { return 0.0; }
  int columns() const override { return n_; }
  void regressors(double, const State&, double*) const override {}
  std::optional<Params> parameters(double, const double*, const State&) const override {
    return Params{};
  }
  int n_;
};

TEST(Effects, AUnitWithMoreColumnsThanTheCapIsRefused) {
  EXPECT_NO_THROW(check_columns(Wide(kMaxColumns)));
  try {
    check_columns(Wide(kMaxColumns + 1));
    ADD_FAILURE() << "a unit of " << kMaxColumns + 1 << " columns was accepted";
  } catch (const std::logic_error& e) {
    EXPECT_NE(std::string(e.what()).find("'wide' has 9 regressor columns"), std::string::npos)
        << e.what();
  }
  for (const Effect* e : library()) EXPECT_LE(e->columns(), kMaxColumns) << e->id();
}

TEST(Effects, IdsAndParameterNamesAreTheDocumentedOnes) {
  std::ifstream f(MAGLEAD_EFFECTS_DOC);
  ASSERT_TRUE(f) << "docs/effects.md not found at " << MAGLEAD_EFFECTS_DOC;
  std::stringstream doc;
  doc << f.rdbuf();
  const std::string text = doc.str();
  for (const Effect* e : library()) {
    EXPECT_NE(text.find("`" + std::string(e->id()) + "`"), std::string::npos) << e->id();
    if (e->columns() == 0) continue;  // events: their fields are the events' own
    for (const auto& p : e->params())
      EXPECT_NE(text.find("`" + p.name + "`"), std::string::npos) << e->id() << "." << p.name;
  }
  EXPECT_EQ(find("no_such_effect"), nullptr);
  EXPECT_THROW(check(*find("offset"), {{"force_n", 1.0}}), std::invalid_argument);
  EXPECT_FALSE(plausible(*find("coupling_gain_error"), {{"gain", 3.0}}, {}));
}

// A play whose lag b/2 lies within half a count of the phase is what the encoders' rounding holds
// where nothing moves: not a backlash on that actuator, one on an actuator that resolves it.
TEST(EffectLibrary, APlayBelowACountOfThePhaseIsNotBacklash) {
  const Effect& backlash = *find("backlash");
  EXPECT_FALSE(plausible(backlash, {{"backlash_rad", 0.007}}, {.phase_count_rad = 0.0157}));
  EXPECT_TRUE(plausible(backlash, {{"backlash_rad", 0.007}}, {.phase_count_rad = 0.005}));
  EXPECT_TRUE(plausible(backlash, {{"backlash_rad", 0.025}}, {.phase_count_rad = 0.0157}));
  EXPECT_TRUE(plausible(backlash, {{"backlash_rad", 0.007}}, {}));  // the count not known
  // The bound is the play's own: a negative gain error stays judged by its range alone.
  EXPECT_TRUE(plausible(*find("offset"), {{"offset_n", -0.2}},
                        {.force_n = 44.0, .phase_count_rad = 0.0157}));
}

// A range in the actuator's own scales: the same friction is plausible on a drive that produces
// more than it, not on one that could never overcome it; no actuator's size sits in a unit.
TEST(EffectLibrary, RangesScaleWithTheActuator) {
  const Effect& coulomb = *find("coulomb_friction");
  EXPECT_TRUE(plausible(coulomb, {{"coulomb_n", 30.0}}, {.force_n = 44.0, .speed_m_s = 0.1}));
  EXPECT_FALSE(plausible(coulomb, {{"coulomb_n", 30.0}}, {.force_n = 20.0, .speed_m_s = 0.1}));
  EXPECT_TRUE(plausible(coulomb, {{"coulomb_n", 300.0}}, {.force_n = 500.0, .speed_m_s = 0.1}));
  EXPECT_FALSE(plausible(coulomb, {{"coulomb_n", -1.0}}, {}));  // scale unknown: the sign only
  EXPECT_TRUE(plausible(coulomb, {{"coulomb_n", 1e3}}, {}));
  // A viscous force at the top speed beyond what the drive produces is not viscous friction.
  const Effect& viscous = *find("viscous_friction");
  EXPECT_TRUE(
      plausible(viscous, {{"viscous_n_s_per_m", 400.0}}, {.force_n = 44.0, .speed_m_s = 0.1}));
  EXPECT_FALSE(
      plausible(viscous, {{"viscous_n_s_per_m", 500.0}}, {.force_n = 44.0, .speed_m_s = 0.1}));
  // A heavy axis's moving mass is a mass (the EMPS carriage weighs 95 kg).
  EXPECT_TRUE(plausible(*find("mass_error"), {{"nut_mass_kg", 95.0}}, {.force_n = 100.0}));
  EXPECT_FALSE(plausible(*find("mass_error"), {{"nut_mass_kg", -0.1}}, {.force_n = 100.0}));
}

// A ripple is named only where the samples see it repeat: a position ripple whose period is
// longer than the travel covered, or an angle ripple over less than one screw turn, is any
// smooth function there (a spring, a gain). Not known (0): not applied.
TEST(EffectLibrary, RipplesAreResolvedOnlyOverAPeriodSeen) {
  const Effect& position = *find("position_ripple");
  EXPECT_TRUE(position.resolved_at(0.010, {.travel_m = 0.012}));
  EXPECT_FALSE(position.resolved_at(0.010, {.travel_m = 0.0024}));
  EXPECT_TRUE(position.resolved_at(0.010, {}));
  const Effect& angle = *find("angle_ripple");
  EXPECT_TRUE(angle.resolved_at(0.0, {.turn_rad = 7.0}));
  EXPECT_FALSE(angle.resolved_at(0.0, {.turn_rad = 2.7}));
  EXPECT_TRUE(find("coupling_gain_error")->resolved_at(0.0, {.travel_m = 1e-4, .turn_rad = 0.1}));
}

// sensor_delay against the balance itself: a heavy nut (2.5 kg, 20 N·s/m, 12 N Coulomb) sliding
// one way on a wavy motion under a sinusoidal coupling, the load cell reading the force that
// balances it. Read τ late, every term but the load cell is from t − τ: the missing force is
// F_ext(t − τ) − F_ext(t), which the unit must give from the delayed state to first order in τ.
// With the coupling term alone (k φ̇, the law before) a third of it was missing here (M p⃛).
TEST(EffectLibrary, SensorDelayIsWhatTheDelayDoesToTheWholeBalance) {
  const double m = 2.5, c = 20.0, fc = 12.0, k = 25.0, tau = 0.002;
  const double w = 2 * std::numbers::pi * 3.0, w2 = 2 * std::numbers::pi * 2.0;
  State at;  // the motion and coupling at time t
  at.nut_mass_kg = m, at.viscous_n_s_per_m = c, at.coulomb_n = fc;
  const auto state = [&](double t) {
    State s = at;
    s.p_m = 0.05 * t + 0.002 * std::sin(w * t);
    s.v_m_s = 0.05 + 0.002 * w * std::cos(w * t);  // > 0: sliding one way
    s.a_m_s2 = -0.002 * w * w * std::sin(w * t);
    s.jerk_m_s3 = -0.002 * w * w * w * std::cos(w * t);
    s.phi_rad = 0.3 * std::sin(w2 * t);
    s.phi_rate_rad_s = 0.3 * w2 * std::cos(w2 * t);
    s.coupling_n = -k * std::sin(s.phi_rad);
    s.coupling_slope_n_per_rad = -k * std::cos(s.phi_rad);
    return s;
  };
  const auto load_n = [&](double t) {  // M p̈ = F_m − C v − F_c + F_ext
    const State s = state(t);
    return m * s.a_m_s2 - s.coupling_n + c * s.v_m_s + fc;
  };
  const Effect& e = *find("sensor_delay");
  double missing2 = 0, error2 = 0;
  for (double t = 0; t < 1.0; t += 0.001) {
    const double missing = load_n(t - tau) - load_n(t);
    const double law = e.force_n({{"delay_s", tau}}, state(t - tau));
    missing2 += missing * missing;
    error2 += (law - missing) * (law - missing);
  }
  // Second order in τ: about ωτ/2 of it at the fastest component (2 % here).
  EXPECT_LT(std::sqrt(error2 / missing2), 0.05);
}

}  // namespace
}  // namespace maglead::effects
