// The model file: the format the analysis tool writes back must load into the twin.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdlib>
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
  m.terms.push_back({"asymmetric_friction",
                     true,
                     "at reversals",
                     {{"coulomb_pos_n", 6.75}, {"coulomb_neg_n", 5.25}}});
  m.terms.push_back({"offset", true, "", {{"offset_n", -1.5}}});
  m.terms.push_back(
      {"angle_ripple", false, "", {{"relative_amplitude", 0.04}, {"phase_rad", 1.0}}});
  m.terms.push_back({"backlash", true, "", {{"backlash_rad", 0.002}}});
  save_twin_model(tmp("model_rt.toml"), m, "test");
  const TwinModel r = load_twin_model(tmp("model_rt.toml"));
  EXPECT_EQ(r.source, m.source);
  EXPECT_DOUBLE_EQ(r.coulomb_n, 6.0);
  ASSERT_EQ(r.terms.size(), 4u);
  EXPECT_EQ(r.terms[0].id, "asymmetric_friction");
  EXPECT_DOUBLE_EQ(r.terms[0].get("coulomb_pos_n", 0.0), 6.75);
  EXPECT_EQ(r.terms[0].note, "at reversals");
  EXPECT_DOUBLE_EQ(r.terms[1].get("offset_n", 0.0), -1.5);
  EXPECT_FALSE(r.terms[2].enabled);
  EXPECT_DOUBLE_EQ(r.terms[2].get("phase_rad", 0.0), 1.0);
  EXPECT_DOUBLE_EQ(r.terms[3].get("backlash_rad", 0.0), 0.002);
}

TEST(ModelFile, LargeWholeNumbersRoundTripAsFloats) {
  // Written as digits alone (85555555555555557376) TOML reads an integer beyond 64 bits and
  // refuses the file (found by fuzz_config): a large whole number carries an exponent.
  TwinModel m;
  m.terms.push_back({"offset", false, "", {{"offset_n", 85555555555555557376.0}}});
  m.terms.push_back({"backlash", false, "", {{"backlash_rad", -1e300}}});
  save_twin_model(tmp("model_large.toml"), m);
  const TwinModel r = load_twin_model(tmp("model_large.toml"));
  ASSERT_EQ(r.terms.size(), 2u);
  EXPECT_EQ(r.terms[0].get("offset_n", 0.0), 85555555555555557376.0);
  EXPECT_EQ(r.terms[1].get("backlash_rad", 0.0), -1e300);
}

TEST(ModelFile, ControlCharactersInTextRoundTrip) {
  // A note or source holding control characters (read from a file as "\u0001", "\r") is
  // written back escaped; it was written raw, which TOML refuses (found by fuzz_config).
  TwinModel m;
  m.source = std::string("bench\r\x01\x7F\t\"7\"\nrun");
  m.terms.push_back({"offset", true, std::string("note\x1F\x02", 6), {{"offset_n", 1.0}}});
  save_twin_model(tmp("model_ctrl.toml"), m);
  const TwinModel r = load_twin_model(tmp("model_ctrl.toml"));
  EXPECT_EQ(r.source, m.source);
  ASSERT_EQ(r.terms.size(), 1u);
  EXPECT_EQ(r.terms[0].note, m.terms[0].note);
}

std::string load_error(const std::string& path) {
  try {
    load_twin_model(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "no error";
}

TEST(ModelFile, TyposAreErrorsNamingTheKeyAndWhereItIs) {
  const std::string fmt = std::string(kModelFormatLine) + "\n";
  std::ofstream(tmp("bad_id.toml"))
      << fmt << "[model]\nnut_mass_kg = 0.12\n[[term]]\nid = \"ofset\"\n";
  std::ofstream(tmp("bad_par.toml")) << fmt << "[model]\n[[term]]\nid = \"offset\"\nforce = 1.0\n";
  std::ofstream(tmp("bad_key.toml")) << fmt << "[model]\nmass_kg = 0.12\n";
  std::ofstream(tmp("bad_num.toml"))
      << fmt << "[model]\nnut_mass_kg = 0.12\ncoulomb_n =   \"7.5\"\n";
  const std::string id = load_error(tmp("bad_id.toml"));
  EXPECT_NE(id.find("'ofset'"), std::string::npos) << id;
  EXPECT_NE(id.find("bad_id.toml:4:1:"), std::string::npos) << id;  // the [[term]] header
  const std::string par = load_error(tmp("bad_par.toml"));
  EXPECT_NE(par.find("'force'"), std::string::npos) << par;
  const std::string key = load_error(tmp("bad_key.toml"));
  EXPECT_NE(key.find("'mass_kg'"), std::string::npos) << key;
  EXPECT_NE(key.find("bad_key.toml:3:11:"), std::string::npos) << key;  // the value of mass_kg
  // A misspelt table: the error names what the file holds instead.
  std::ofstream(tmp("bad_table.toml")) << fmt << "[modle]\nnut_mass_kg = 0.12\n";
  const std::string table = load_error(tmp("bad_table.toml"));
  EXPECT_NE(table.find("missing [model] table (the file has: modle)"), std::string::npos) << table;
  const std::string num = load_error(tmp("bad_num.toml"));
  EXPECT_NE(num.find("bad_num.toml:4:15: [model] coulomb_n must be a number"), std::string::npos)
      << num;
}

TEST(ModelFile, SyntaxErrorNamesLineAndColumn) {
  std::ofstream(tmp("syntax.toml")) << kModelFormatLine << "\n[model]\nnut_mass_kg = = 0.12\n";
  const std::string e = load_error(tmp("syntax.toml"));
  EXPECT_NE(e.find("syntax.toml:3:"), std::string::npos) << e;
  EXPECT_EQ(e.find("syntax.toml:3:1:"), std::string::npos) << "a column, not just the line: " << e;
}

TEST(ModelFile, FormatLineIsRequired) {
  std::ofstream(tmp("no_format.toml")) << "[model]\nnut_mass_kg = 0.12\n";
  std::ofstream(tmp("other_format.toml")) << "# format: mls-recording/1\n[model]\n";
  const std::string none = load_error(tmp("no_format.toml"));
  EXPECT_NE(none.find("no_format.toml:1:1:"), std::string::npos) << none;
  EXPECT_NE(none.find("# format: maglead-model/1"), std::string::npos) << none;
  const std::string other = load_error(tmp("other_format.toml"));
  EXPECT_NE(other.find("mls-recording/1"), std::string::npos) << other;
  // A format line naming no format (found by fuzz_config: it threw std::out_of_range).
  for (const char* line : {"# format:", "# format:   "}) {
    std::ofstream(tmp("empty_format.toml")) << line << "\n[model]\n";
    const std::string empty = load_error(tmp("empty_format.toml"));
    EXPECT_NE(empty.find("empty_format.toml:1:11: format '' is not maglead-model/1"),
              std::string::npos)
        << empty;
  }
  // What save_twin_model writes carries it.
  save_twin_model(tmp("saved.toml"), TwinModel{});
  EXPECT_NO_THROW(check_model_format(tmp("saved.toml")));
}

// What `maglead analyze` writes (simulate, analyze, load: the commands a user runs) is what the
// twin reads: the fitted term comes back with its value and changes the twin's dynamics.
TEST(ModelFile, TheAnalysisWritesWhatTheTwinReads) {
  const std::string dir = tmp("analyzed_" + std::to_string(::getpid()));
  const std::string bin = MAGLEAD_BIN, cfg = MAGLEAD_CONFIG_DIR;
  const double offset_n = 3.0;
  const std::string sim = bin + " simulate --scenario hand-push --duration 20s --seed 3" +
                          " --effect offset=" + std::to_string(offset_n) + " --config " + cfg +
                          " --out " + dir + ".csv > /dev/null";
  ASSERT_EQ(std::system(sim.c_str()), 0) << sim;
  const std::string an = bin + " analyze --recording " + dir + ".csv --out " + dir + " --config " +
                         cfg + " > /dev/null";
  ASSERT_EQ(std::system(an.c_str()), 0) << an;
  const TwinModel m = load_twin_model(dir + "/model_corrected.toml");
  const ModelTerm* found = nullptr;
  for (const auto& t : m.terms)
    if (t.id == "offset" && t.enabled) found = &t;
  ASSERT_NE(found, nullptr) << "the analysis wrote no enabled offset term";
  // The offset is a mean over thousands of sliding samples; the load cell's noise (0.1 N, one
  // sample's standard deviation) bounds its error with a wide margin.
  EXPECT_NEAR(found->get("offset_n", 0.0), offset_n, 0.1);
  EXPECT_NE(m.source.find(".csv"), std::string::npos) << m.source;  // it says what it came from
  const ActuatorParams act;
  const NutModel base(act, paper_calibration().periodic, TwinModel{});
  const NutModel read(act, paper_calibration().periodic, m);
  const double screw = rest_angle_rad(0.02, act.lead_m);
  EXPECT_NEAR(read.drive_force_n(0, screw, 0.02, 0, 0) - base.drive_force_n(0, screw, 0.02, 0, 0),
              found->get("offset_n", 0.0), 1e-9);
}

TEST(ModelFile, TermsChangeTheDynamics) {
  // An offset term moves the stuck nut's break-away: +6 N of offset plus F_m(0) = 4.28 N
  // exceeds F_c = 7.5 N, so the same inputs now make the nut slide.
  const ActuatorParams act;
  TwinModel with_offset;
  with_offset.terms.push_back({"offset", true, "", {{"offset_n", 6.0}}});
  const NutModel base(act, paper_calibration().periodic, TwinModel{});
  const NutModel off(act, paper_calibration().periodic, with_offset);
  const double screw = rest_angle_rad(0.02, act.lead_m);
  EXPECT_EQ(base.mode_at_rest(base.drive_force_n(0, screw, 0.02, 0, 0)), FrictionMode::stick);
  EXPECT_EQ(off.mode_at_rest(off.drive_force_n(0, screw, 0.02, 0, 0)), FrictionMode::slide_pos);
}

// Every effect of the library that has a law changes what the twin computes: no term is
// accepted and then ignored. Parameters at a tenth of the way into each plausible range.
TEST(ModelFile, EveryLawInTheLibraryIsSimulated) {
  const ActuatorParams act;
  const NutModel base(act, paper_calibration().periodic, TwinModel{});
  for (const auto* e : effects::library()) {
    if (e->columns() == 0) continue;  // events (step-out, disturbances), not laws
    TwinModel m;
    auto& t = m.term(std::string(e->id()));
    for (const auto& p : e->params()) t.set(p.name, p.min + 0.1 * (p.max - p.min) + 1e-3 * p.max);
    const NutModel tw(act, paper_calibration().periodic, m);
    bool differs = tw.mass_kg() != base.mass_kg();
    for (int dir : {-1, 1}) {
      differs |= tw.breakaway_n(dir) != base.breakaway_n(dir);
      differs |= tw.sliding_friction_n(dir, 0.002) != base.sliding_friction_n(dir, 0.002);
    }
    for (double pos : {0.001, 0.02}) {
      const double screw = rest_angle_rad(pos, act.lead_m) + 0.3;
      differs |= tw.drive_force_n(30.0, screw, pos, 0.01, 5.0, 2.0, 100.0) !=
                 base.drive_force_n(30.0, screw, pos, 0.01, 5.0, 2.0, 100.0);
    }
    EXPECT_TRUE(differs) << e->id() << " is accepted by the twin but changes nothing";
  }
}

}  // namespace
}  // namespace maglead::twin
