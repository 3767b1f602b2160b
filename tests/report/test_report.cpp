// The report library's helpers: downsampling that keeps what a reader must see, escaping and
// base64 that round-trip, and the anomaly page's plain-language rules.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "../test_tmp.hpp"
#include "analysis_part.hpp"
#include "effect_text.hpp"
#include "image_encode.hpp"
#include "maglead/effects/effect.hpp"
#include "maglead/report/analysis_page.hpp"
#include "maglead/report/html.hpp"
#include "maglead/report/plot.hpp"
#include "maglead/report/time_chart.hpp"

namespace maglead::report {
namespace {

std::vector<double> ramp(std::size_t n) {
  std::vector<double> t(n);
  for (std::size_t i = 0; i < n; ++i) t[i] = 0.001 * static_cast<double>(i);
  return t;
}

// A one-sample spike in an hour at 1 kHz survives the reduction to a few thousand rows, and the
// rows stay in time order within the budget.
TEST(Envelope, KeepsASingleSampleSpikeAndStaysWithinBudget) {
  const std::size_t n = 3'600'000, spike = 2'345'678, dip = 77;
  const auto t = ramp(n);
  std::vector<double> y(n, 0.0), flat(n, 1.0);
  y[spike] = 50.0;
  y[dip] = -3.0;
  const auto rows = envelope_rows(t, 0, {y, flat}, 6000);
  EXPECT_LE(rows.size(), 6000u);
  EXPECT_GT(rows.size(), 1000u);
  for (std::size_t k = 1; k < rows.size(); ++k) ASSERT_LT(rows[k - 1], rows[k]);
  EXPECT_NE(std::find(rows.begin(), rows.end(), spike), rows.end());
  EXPECT_NE(std::find(rows.begin(), rows.end(), dip), rows.end());
}

TEST(Envelope, ShortRecordingsAreDrawnWhole) {
  const auto t = ramp(500);
  const std::vector<double> y(500, 2.0);
  const auto rows = envelope_rows(t, 20, {y}, 1000);
  ASSERT_EQ(rows.size(), 480u);
  EXPECT_EQ(rows.front(), 20u);  // the start-up samples before `first` are not drawn
  EXPECT_EQ(rows.back(), 499u);
}

TEST(Envelope, GapsDoNotHideTheRest) {
  const std::size_t n = 100'000;
  const auto t = ramp(n);
  std::vector<double> y(n, std::numeric_limits<double>::quiet_NaN());
  y[n / 2] = 7.0;  // the only finite value
  const auto rows = envelope_rows(t, 0, {y}, 1000);
  EXPECT_NE(std::find(rows.begin(), rows.end(), n / 2), rows.end());
}

TEST(TimeChart, LabelsCannotCloseTheScript) {
  const auto t = ramp(3);
  TimeChart c;
  c.id = "x";
  c.t_s = &t;
  c.series.push_back({"</script><b>", {1.0, std::nan(""), 3.0}});
  const std::string h = time_chart_html(c);
  EXPECT_EQ(h.find("</script><b>"), std::string::npos);
  EXPECT_NE(h.find("[0.001,null]"), std::string::npos) << "NaN is a gap, not a number";
}

TEST(Html, EscapesAndEncodes) {
  EXPECT_EQ(escape_html("a<b & \"c\">"), "a&lt;b &amp; &quot;c&quot;&gt;");
  EXPECT_EQ(base64(""), "");
  EXPECT_EQ(base64("f"), "Zg==");
  EXPECT_EQ(base64("fo"), "Zm8=");
  EXPECT_EQ(base64("foo"), "Zm9v");
  EXPECT_EQ(base64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(base64(std::string("\xff\x00\x10", 3)), "/wAQ");
  EXPECT_EQ(number(-0.2014), "−0.201");
  EXPECT_EQ(number(std::nan("")), "–");
  EXPECT_EQ(number(2000.0), "2000");
  EXPECT_EQ(number(0.000123), "0.000123");
}

// A rotary run with no effect named whose misfit remains (a cogging torque, say) is no all-clear:
// green is for "nothing missing" judged alone; the misfit's conclusion and the "Nothing" box are
// in the attention style, a conclusion not judged in the neutral one.
analysis::AnalysisResult result_concluding(const std::string& conclusion,
                                           std::optional<bool> nothing_missing) {
  analysis::AnalysisResult r;
  r.findings.system = "rotary";
  r.findings.recording = "servo.csv";
  r.findings.conclusion = conclusion;
  r.findings.nothing_missing = nothing_missing;
  r.corrected.system = "rotary";
  r.headline = conclusion;
  return r;
}

std::string page_of(const analysis::AnalysisResult& r, const std::string& name) {
  const std::string dir = test_tmp_dir() + "/" + name;
  write_analysis_outputs(r, dir);
  std::ifstream in(dir + "/index.html");
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(AnalysisPage, GreenIsForNothingMissingAlone) {
  const std::string misfit =
      "a misfit of 0.0207 N·m RMS remains (noise floor 0.00818 N·m) that no library "
      "effect explains; check the drive's torque constant";
  const std::string page = page_of(result_concluding(misfit, false), "misfit");
  EXPECT_EQ(page.find("class=\"ok\""), std::string::npos) << page;
  EXPECT_NE(page.find("<p class=\"bad\" id=\"conclusion\"><b>a misfit of"), std::string::npos);
  EXPECT_NE(page.find("<p class=\"bad\">Nothing: the analysis adds no effect."), std::string::npos);
  EXPECT_NE(page.find("but it does not explain the recording: a misfit of"), std::string::npos);

  const std::string nothing = "nothing is missing: no effect explains a significant part";
  const std::string ok = page_of(result_concluding(nothing, true), "nothing");
  EXPECT_NE(ok.find("<p class=\"ok\" id=\"conclusion\">"), std::string::npos) << ok;
  EXPECT_NE(ok.find("<p class=\"ok\">Nothing: the analysis adds no effect."), std::string::npos);

  // The actuator leaves nothing_missing unset: its conclusion alone says so.
  const auto actuator =
      result_concluding(nothing + "; it cannot name changes smaller than: x", std::nullopt);
  EXPECT_STREQ(conclusion_class(actuator.findings), "ok");
  const auto unjudged = result_concluding("not judged: too little sliding", std::nullopt);
  EXPECT_STREQ(conclusion_class(unjudged.findings), "unjudged");
  EXPECT_STREQ(conclusion_class(result_concluding("found: x", false).findings), "bad");

  // Nothing missing among the laws judged, one law not judged: amber, with the law named, in
  // the box and in the headline at the top; never the green of an all-clear.
  auto partly = result_concluding(nothing, true);
  analysis::Rejected skipped;
  skipped.id = "mass_error";
  skipped.reason = std::string(analysis::kNotJudged) + "the moves are too slow to show it";
  partly.findings.not_selected.push_back(skipped);
  partly.headline = "nothing missing: the model explains the recording to 0.01 N·m RMS; " +
                    std::string(analysis::kNotJudged) + "mass_error (too slow)";
  const std::string amber = page_of(partly, "partly");
  EXPECT_EQ(amber.find("class=\"ok\""), std::string::npos) << amber;
  EXPECT_NE(amber.find("<p class=\"unjudged\" id=\"headline\">"), std::string::npos) << amber;
  EXPECT_NE(amber.find("but not every law was judged on this recording: mass_error"),
            std::string::npos)
      << amber;
  partly.headline = "found: x; " + std::string(analysis::kNotJudged) + "mass_error (too slow)";
  EXPECT_NE(page_of(partly, "found_partly").find("<p class=\"bad\" id=\"headline\">"),
            std::string::npos);
}

}  // namespace
}  // namespace maglead::report

namespace maglead::report {
namespace {

// Every parameter of the effect library is shown with a unit read off its name
// (docs/effects.md: "the unit is part of the name"), except the few that are ratios or counts.
// A load cell set aside for reading one value throughout is a wiring fault, said as such, not
// one in another unit.
TEST(AnomalyHeadline, AConstantLoadCellIsSaidAsItsWiring) {
  analysis::Anomaly a;
  a.has_load_cell = true;
  analysis::set_aside_load_cell(a, "r.csv: not judged: the load cell reads a constant 0 N", 0.0);
  AnalysisOutcome o;
  o.status = AnalysisOutcome::Status::failed;
  const std::string h = anomaly_headline(a, o);
  EXPECT_NE(h.find("force estimate (the load cell reads a constant 0 N: check its wiring)"),
            std::string::npos)
      << h;
  EXPECT_EQ(h.find("not the load in newtons"), std::string::npos) << h;
  analysis::set_aside_load_cell(a, "r.csv: load_force_n cannot be the load in newtons");
  EXPECT_NE(anomaly_headline(a, o).find("load_force_n is not the load in newtons"),
            std::string::npos);
}

TEST(EffectText, EveryLibraryParameterHasItsUnit) {
  const std::set<std::string> dimensionless{"gain", "relative_amplitude", "max_reduction", "count"};
  for (const auto* e : effects::library())
    for (const auto& p : e->params()) {
      const std::string h = parameter_html(std::string(e->id()), p.name, 1.5);
      const bool has_unit =
          h.find("= 1.5 <") == std::string::npos && h.find("= 1.5 ") != std::string::npos;
      EXPECT_TRUE(has_unit || dimensionless.count(p.name)) << e->id() << "." << p.name << ": " << h;
    }
  EXPECT_NE(parameter_html("gain_drift", "gain_change_per_min", -0.2).find("−0.2 1/min"),
            std::string::npos);
  EXPECT_NE(parameter_html("viscous_friction", "viscous_n_s_per_m", 3).find("3 N·s/m"),
            std::string::npos);
  EXPECT_NE(parameter_html("spring", "stiffness_n_per_m", 2000).find("2000 N/m"),
            std::string::npos);
  EXPECT_NE(parameter_html("gain_drift", "gain_change_per_min", 1)
                .find("rate r of the relative coupling gain)"),
            std::string::npos)
      << "the library's meaning, without its own [unit]";
  EXPECT_EQ(effect_title("stribeck_friction"), "stribeck friction");
}

// On a rotary axis the laws and meanings are a shaft's (effects/axis_kind.hpp, AxisKind::words):
// a torque τ on the shaft along +θ, speed ω; a linear axis keeps the library's text, and names
// with units in them are left to name_of.
TEST(EffectText, ARotaryAxisSpeaksOfTorqueAndAngle) {
  const auto& rotary = effects::rotary_axis();
  EXPECT_EQ(effect_law("viscous_friction", &rotary), "τ = -C ω");
  EXPECT_EQ(effect_law("viscous_friction"), "F = -C v");
  EXPECT_EQ(effect_law("asymmetric_friction", &rotary),
            "τ_f = τ_c+ (ω > 0), -τ_c- (ω < 0); break-away likewise");
  EXPECT_NE(parameter_html("offset", "offset_n_m", 0.1, 0.0, rotary)
                .find("(constant torque on the shaft along +θ)"),
            std::string::npos);
  EXPECT_NE(parameter_html("asymmetric_friction", "coulomb_neg_n_m", 0.1, 0.0, rotary)
                .find("(friction moving -θ)"),
            std::string::npos);
  EXPECT_NE(parameter_html("offset", "offset_n", 0.1).find("(constant force on the nut along +p)"),
            std::string::npos);
  EXPECT_EQ(rotary.words("nut_mass_kg: moving mass M"), "nut_mass_kg: moving inertia J");
  // A servo or a ball screw has no load cell: the offset's law says so only on the actuator.
  EXPECT_EQ(effect_law("offset", &rotary), "τ = τ_o (constant, along +θ)");
  EXPECT_EQ(effect_law("offset", &effects::linear_axis()), "F = F_o (constant, along +p)");
  EXPECT_EQ(effect_law("offset"), "F = F_o (constant, along +p, unseen by the load cell)");
}

// A parameter with its standard error is shown at the digits the error allows, as analyze prints
// it; a grid value (no error) as before.
TEST(EffectText, ParameterWithItsStandardErrorAtItsDigits) {
  EXPECT_NE(
      parameter_html("spring", "stiffness_n_per_m", 199.98962, 0.013).find("= 199.990 ± 0.013 N/m"),
      std::string::npos);
  EXPECT_NE(parameter_html("angle_ripple", "phase_rad", -1.20213, 0.0143).find("= −1.202 ± 0.014"),
            std::string::npos);
  EXPECT_NE(parameter_html("position_ripple", "period_m", 0.0025, 1e-18).find("= 0.0025 m"),
            std::string::npos);
}

}  // namespace
}  // namespace maglead::report

namespace {

// A 5×3 BGR image, a row padded to 16 bytes as OpenCV pads a sub-matrix's rows.
struct SmallImage {
  std::vector<unsigned char> bytes = std::vector<unsigned char>(std::size_t{3} * 16, 200);
  maglead::plot::BgrImage view() const { return {bytes.data(), 5, 3, 16}; }
};

std::uint32_t big_endian_at(const std::string& s, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) v = v << 8 | static_cast<unsigned char>(s[at + i]);
  return v;
}

}  // namespace

// OpenCV's fonts draw '?' for anything not ASCII: every figure's text is spelled in ASCII first,
// so a rotary axis's "[N·m]" is "[N*m]", never "[N??m]".
TEST(Plot, FigureTextIsSpelledInAscii) {
  using maglead::plot::ascii_label;
  EXPECT_EQ(ascii_label("drive torque [N·m]"), "drive torque [N*m]");
  EXPECT_EQ(ascii_label("inertia [kg·m²]"), "inertia [kg*m^2]");
  EXPECT_EQ(ascii_label("error [µm], −3 … 3"), "error [um], -3 ... 3");
  EXPECT_EQ(ascii_label("angle θ [rad], speed ω [rad·s⁻¹], τ ± 1°"),
            "angle theta [rad], speed omega [rad*s^-1], tau +/- 1deg");
  EXPECT_EQ(ascii_label("plain [N]"), "plain [N]");
  const std::string unknown = ascii_label("a ☃ b 漢");
  EXPECT_EQ(unknown, "a _ b _");
  for (const std::string& s : {ascii_label("N·m·s/rad"), ascii_label("ünïcödé"), unknown}) {
    EXPECT_TRUE(std::all_of(s.begin(), s.end(), [](char c) {
      return static_cast<unsigned char>(c) < 0x80 && c != '?';
    })) << s;
  }
}

TEST(ImageEncode, PngCarriesTheImagesSize) {
  const std::string png = maglead::plot::encode_png(SmallImage{}.view());
  ASSERT_GT(png.size(), 33U);
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_EQ(png.substr(12, 4), "IHDR");
  EXPECT_EQ(big_endian_at(png, 16), 5U);  // width
  EXPECT_EQ(big_endian_at(png, 20), 3U);  // height
}

TEST(ImageEncode, JpegIsAJpeg) {
  const std::string jpg = maglead::plot::encode_jpeg(SmallImage{}.view(), 95);
  ASSERT_GT(jpg.size(), 4U);
  EXPECT_EQ(jpg.substr(0, 2), "\xff\xd8");            // start of image
  EXPECT_EQ(jpg.substr(jpg.size() - 2), "\xff\xd9");  // end of image
}

TEST(ImageEncode, AnEmptyImageIsRefusedWithTheLibrarysReason) {
  const maglead::plot::BgrImage empty{nullptr, 0, 0, 0};
  const auto message_of = [&](auto encode) -> std::string {
    try {
      (void)encode();
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "(no error)";
  };
  const std::string png = message_of([&] { return maglead::plot::encode_png(empty); });
  const std::string jpg = message_of([&] { return maglead::plot::encode_jpeg(empty, 95); });
  EXPECT_EQ(png.rfind("PNG encoding failed: ", 0), 0U) << png;
  EXPECT_GT(png.size(), std::string("PNG encoding failed: ").size()) << png;
  EXPECT_EQ(jpg.rfind("JPEG encoding failed: ", 0), 0U) << jpg;
  EXPECT_GT(jpg.size(), std::string("JPEG encoding failed: ").size()) << jpg;
}
