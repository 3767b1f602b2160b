// The model file: the format the analysis tool writes back must load into the twin.
#include <gtest/gtest.h>

#include <fstream>
#include <stdexcept>

#include "maglead/twin/hybrid_twin.hpp"
#include "maglead/twin/model.hpp"

namespace maglead::twin {
namespace {

std::string tmp(const std::string& name) { return std::string(MAGLEAD_TEST_TMP) + "/" + name; }

TEST(ModelFile, RepositoryModelLoadsWithPaperValues) {
  const TwinModel m = load_twin_model(std::string(MAGLEAD_CONFIG_DIR) + "/model.toml");
  EXPECT_DOUBLE_EQ(m.nut_mass_kg, 0.12);
  EXPECT_DOUBLE_EQ(m.viscous_n_s_per_m, 2.0);
  EXPECT_DOUBLE_EQ(m.coulomb_n, 7.5);
}

TEST(ModelFile, RoundTripKeepsTermsAndParameters) {
  TwinModel m;
  m.source = "analysis of \"run 7\"";
  m.coulomb_n = 6.0;
  m.terms.push_back({"asymmetric_friction", true, "at reversals", {{"n", 0.75}}});
  m.terms.push_back({"offset", true, "", {{"force_n", -1.5}}});
  m.terms.push_back({"angle_ripple", false, "", {{"n", 0.4}, {"phase_rad", 1.0}}});
  m.terms.push_back({"backlash", true, "", {{"rad", 0.002}}});
  save_twin_model(tmp("model_rt.toml"), m, "test");
  const TwinModel r = load_twin_model(tmp("model_rt.toml"));
  EXPECT_EQ(r.source, m.source);
  EXPECT_DOUBLE_EQ(r.coulomb_n, 6.0);
  ASSERT_EQ(r.terms.size(), 4u);
  EXPECT_EQ(r.terms[0].id, "asymmetric_friction");
  EXPECT_DOUBLE_EQ(r.terms[0].get("n", 0.0), 0.75);
  EXPECT_EQ(r.terms[0].note, "at reversals");
  EXPECT_DOUBLE_EQ(r.terms[1].get("force_n", 0.0), -1.5);
  EXPECT_FALSE(r.terms[2].enabled);
  EXPECT_DOUBLE_EQ(r.terms[2].get("phase_rad", 0.0), 1.0);
  EXPECT_EQ(r.unsimulated_terms(), std::vector<std::string>{"backlash"});
}

TEST(ModelFile, TyposAreErrorsNamingTheKey) {
  std::ofstream(tmp("bad_id.toml")) << "[model]\nnut_mass_kg = 0.12\n[[term]]\nid = \"ofset\"\n";
  std::ofstream(tmp("bad_par.toml")) << "[model]\n[[term]]\nid = \"offset\"\nforce = 1.0\n";
  std::ofstream(tmp("bad_key.toml")) << "[model]\nmass_kg = 0.12\n";
  const auto message = [](const std::string& path) {
    try {
      load_twin_model(path);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message(tmp("bad_id.toml")).find("'ofset'"), std::string::npos);
  EXPECT_NE(message(tmp("bad_par.toml")).find("'force'"), std::string::npos);
  EXPECT_NE(message(tmp("bad_key.toml")).find("'mass_kg'"), std::string::npos);
}

TEST(ModelFile, TermsChangeTheDynamics) {
  // An offset term moves the stuck nut's break-away: +6 N of offset plus F_m(0) = 4.28 N
  // exceeds F_c = 7.5 N, so the same inputs now make the nut slide.
  const ActuatorParams act;
  TwinModel with_offset;
  with_offset.terms.push_back({"offset", true, "", {{"force_n", 6.0}}});
  const NutModel base(act, paper_calibration().periodic, TwinModel{});
  const NutModel off(act, paper_calibration().periodic, with_offset);
  const double screw = rest_angle_rad(0.02, act.lead_m);
  EXPECT_EQ(base.mode_at_rest(base.drive_force_n(0, screw, 0.02, 0, 0)), FrictionMode::stick);
  EXPECT_EQ(off.mode_at_rest(off.drive_force_n(0, screw, 0.02, 0, 0)), FrictionMode::slide_pos);
}

}  // namespace
}  // namespace maglead::twin
