// The headline and the conclusion say what accounts for the recording: events alone are not an
// account of a misfit, and nothing named is not nothing missing on either path.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "maglead/analysis/analysis.hpp"
#include "maglead/analysis/headline.hpp"
#include "maglead/analysis/results.hpp"

namespace {

using maglead::analysis::EffectFinding;
using maglead::analysis::Findings;
using maglead::analysis::ModelFile;
using maglead::analysis::Unexplained;

EffectFinding disturbance_events(std::size_t count) {
  EffectFinding e;
  e.id = "external_disturbance";
  e.parameters = {{"count", static_cast<double>(count), false}};
  e.evidence.events = count;
  return e;
}

/// A recording's findings with its final residual `rms_n` over a floor of 0.1 N.
// What the paths pass beside the findings: `terms` named, what to check, the axis.
maglead::analysis::Concluding checking(
    std::size_t terms, const maglead::effects::AxisKind* kind = &maglead::effects::linear_axis()) {
  maglead::analysis::Concluding c;
  c.terms_named = terms;
  c.check = "the drive's force constant";
  c.kind = kind;
  return c;
}

Findings findings_with_residual(double rms_n) {
  Findings f;
  f.noise_floor_n = 0.1;
  f.final_fit.rms_n = rms_n;
  return f;
}

bool starts_with(const std::string& s, const std::string& head) { return s.rfind(head, 0) == 0; }

TEST(Headline, AForceNoEffectExplainsLeadsBeforeEventsBesideIt) {
  Findings f = findings_with_residual(0.7);
  f.effects.push_back(disturbance_events(4));
  f.unexplained = Unexplained{};
  f.unexplained->message = "a force of 0.7 N no library effect explains plausibly";
  const std::string h = maglead::analysis::headline_of(f, ModelFile{});
  EXPECT_TRUE(starts_with(h, "not explained: a force of 0.7 N")) << h;
  EXPECT_NE(h.find("; events found beside it: external disturbance"), std::string::npos) << h;
}

TEST(Headline, EventsWithAMisfitBesideThemSayTheMisfit) {
  // A short pulse leaves little of its force in the sliding residual (8 N pulses alone: 0.053 N
  // over a 0.1 N floor): 0.7 N left beside events is force they do not account for.
  Findings f = findings_with_residual(0.7);
  f.effects.push_back(disturbance_events(4));
  const std::string h = maglead::analysis::headline_of(f, ModelFile{});
  EXPECT_EQ(h,
            "found: external disturbance count 4 (not in the model); a misfit of 0.7 N RMS "
            "remains beside them (noise floor 0.1 N)");
  maglead::analysis::conclude(f, checking(0));
  EXPECT_TRUE(starts_with(f.conclusion,
                          "events found (external_disturbance); a misfit of 0.7 N RMS remains"))
      << f.conclusion;
  EXPECT_EQ(f.nothing_missing, false);
  // Within twice the floor the residual is the noise: events alone, nothing left.
  Findings quiet = findings_with_residual(0.15);
  quiet.effects.push_back(disturbance_events(4));
  EXPECT_EQ(maglead::analysis::headline_of(quiet, ModelFile{}),
            "found: external disturbance count 4 (not in the model)");
  maglead::analysis::conclude(quiet, checking(0));
  EXPECT_EQ(quiet.conclusion,
            "events found (external_disturbance); no effect explains a significant part of the "
            "held-out error")
      << quiet.conclusion;
}

// A load cell logged in steps coarser than its noise: the floor is the step's rounding, said as
// not measured, and a misfit far above it is a misfit, never "nothing missing".
TEST(Headline, AFloorNotMeasurableBelowTheLoggingStepSaysSo) {
  Findings f = findings_with_residual(1.197);
  f.noise_floor_n = 0.5 / std::sqrt(12.0);
  f.noise_step_n = 0.5;
  EXPECT_EQ(maglead::analysis::headline_of(f, ModelFile{}),
            "a misfit of 1.2 N RMS remains (noise floor not measurable below the 0.5 N logging "
            "step: 0.144 N) that no library effect explains");
}

// No floor and no logging step: a misfit cannot be judged, so the headline says so and never
// "nothing missing" (a floor of 0 is not judged, not no anomaly).
TEST(Headline, AFloorNotMeasurableWithNoStepIsNotJudged) {
  Findings f = findings_with_residual(0.05);
  f.noise_floor_n = 0.0;
  f.noise_step_n = 0.0;
  const std::string h = maglead::analysis::headline_of(f, ModelFile{});
  EXPECT_TRUE(starts_with(h, "not judged: the load cell's noise floor could not be measured")) << h;
  EXPECT_EQ(h.find("nothing missing"), std::string::npos) << h;
  EffectFinding drift;
  drift.id = "gain_drift";
  drift.parameters = {{"gain_change_per_min", -0.29, true}};
  f.effects.push_back(drift);
  const std::string found = maglead::analysis::headline_of(f, ModelFile{});
  EXPECT_NE(found.find("; not judged: the load cell's noise floor could not be measured"),
            std::string::npos)
      << found;
}

TEST(Headline, NothingNamedWithAMisfitSaysTheMisfit) {
  const Findings f = findings_with_residual(0.7);
  const std::string h = maglead::analysis::headline_of(f, ModelFile{});
  EXPECT_TRUE(starts_with(h, "a misfit of 0.7 N RMS remains (noise floor 0.1 N)")) << h;
}

TEST(Headline, ATermFoundWithAMisfitBesideItSaysBoth) {
  Findings f = findings_with_residual(0.45);
  EffectFinding drift;
  drift.id = "gain_drift";
  drift.parameters = {{"gain_change_per_min", -0.29, true}};
  f.effects.push_back(drift);
  const std::string h = maglead::analysis::headline_of(f, ModelFile{});
  EXPECT_TRUE(starts_with(h, "found: gain drift gain_change_per_min -0.29")) << h;
  EXPECT_NE(h.find("; a misfit of 0.45 N RMS remains beside them (noise floor 0.1 N)"),
            std::string::npos)
      << h;
  // Within twice the floor what is left is the recording's noise: nothing more is said.
  f.final_fit.rms_n = 0.15;
  EXPECT_EQ(maglead::analysis::headline_of(f, ModelFile{}).find("misfit"), std::string::npos);
}

TEST(Headline, SlidingLawsNotJudgedAreSaidBesideAFinding) {
  // A break-away named from the stands while the nut never slid: the sliding laws are unjudged.
  Findings f = findings_with_residual(0.15);
  EffectFinding stribeck;
  stribeck.id = "stribeck_friction";
  stribeck.parameters = {{"breakaway_n", 12.0, true}};
  f.effects.push_back(stribeck);
  f.samples = 37037;
  f.sliding_note =
      "the nut barely slides (0 sliding samples of 37037): the sliding fit says little";
  const std::string h = maglead::analysis::headline_of(f, ModelFile{});
  EXPECT_NE(h.find("; the sliding laws not judged: the nut barely slides (0 sliding samples of "
                   "37037)"),
            std::string::npos)
      << h;
  // Enough to fit, if few: judged, and said so.
  f.samples_used = 158;
  EXPECT_NE(maglead::analysis::headline_of(f, ModelFile{}).find("judged on few samples"),
            std::string::npos);
}

TEST(Conclusion, NothingNamedWithAMisfitIsNotNothingMissing) {
  Findings f = findings_with_residual(0.7);
  f.nothing_missing = true;
  maglead::analysis::conclude(f, checking(0));
  EXPECT_TRUE(starts_with(f.conclusion, "a misfit of 0.7 N RMS remains")) << f.conclusion;
  EXPECT_NE(f.conclusion.find("; check the drive's force constant"), std::string::npos);
  EXPECT_EQ(f.nothing_missing, false);

  Findings named = findings_with_residual(0.7);
  maglead::analysis::conclude(named, checking(1));
  EXPECT_EQ(named.conclusion, "1 effect(s) found");
  // A term named and an event (pulses) beside it: two findings, counted as the table lists them.
  maglead::analysis::EffectFinding pulses;
  pulses.id = "external_disturbance";
  pulses.evidence.events = 3;
  named.effects = {maglead::analysis::EffectFinding{}, pulses};
  maglead::analysis::conclude(named, checking(1));
  EXPECT_EQ(named.conclusion, "1 model term and 3 events found");

  Findings quiet = findings_with_residual(0.15);  // within twice the floor: the recording's noise
  maglead::analysis::conclude(quiet, checking(0));
  EXPECT_EQ(quiet.conclusion,
            "nothing is missing: no effect explains a significant part of the held-out error");
}

// On a rotary axis the residual is a torque: the misfit, its noise floor, a near miss's reason
// (the selection writes it for the nut) and what to check say torque and N·m, never force or N.
TEST(Conclusion, ARotaryAxissMisfitIsATorque) {
  Findings f = findings_with_residual(0.7);
  f.system = "rotary";
  maglead::analysis::Rejected near;
  near.id = "offset";
  near.heldout_gain_pct = 60;
  near.reason = std::string(maglead::analysis::kBelowSignificance) +
                ": the force it explains, 0.050 N·m RMS where it acts, is not one the recording "
                "resolves (it must beat 0.100 N·m)";
  f.not_selected.push_back(near);
  maglead::analysis::conclude(f, checking(0, &maglead::effects::rotary_axis()));
  EXPECT_TRUE(starts_with(f.conclusion, "a misfit of 0.7 N·m RMS remains (noise floor 0.1 N·m)"))
      << f.conclusion;
  EXPECT_NE(f.conclusion.find("the torque it explains, 0.050 N·m"), std::string::npos)
      << f.conclusion;
  EXPECT_NE(f.conclusion.find("check the drive's torque constant"), std::string::npos)
      << f.conclusion;
  EXPECT_EQ(f.conclusion.find("force"), std::string::npos) << f.conclusion;
  ModelFile rotary;
  rotary.system = "rotary";
  const Findings quiet = findings_with_residual(0.15);
  const std::string h = maglead::analysis::headline_of(quiet, rotary);
  EXPECT_NE(h.find("N·m RMS (noise floor 0.1 N·m)"), std::string::npos) << h;
}

}  // namespace
