// The actuator analysis end to end: runs the stages of actuator_analysis.cpp and turns their
// typed results into the analysis result (analysis.json content, corrected model, figures).
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "actuator_analysis.hpp"
#include "maglead/analysis/analysis.hpp"

namespace maglead::analysis {
namespace {

using Json = nlohmann::json;

Json params_json(const effects::Params& p) {
  Json j = Json::object();
  for (const auto& [k, v] : p) j[k] = v;
  return j;
}

std::string fmt(double v, int prec = 3) {
  std::ostringstream o;
  o.precision(prec);
  o << v;
  return o.str();
}

actuator::Baseline baseline_of(const ModelFile& m) {
  actuator::Baseline b;
  b.nut_mass_kg = m.nut_mass_kg;
  b.viscous_n_s_per_m = m.viscous_n_s_per_m;
  b.coulomb_n = m.coulomb_n;
  for (const auto& t : m.terms) {
    if (!t.enabled) continue;
    const auto* e = effects::find(t.id);
    if (!e) throw std::invalid_argument("model term '" + t.id + "' is not in the effect library");
    effects::Params p(t.parameters.begin(), t.parameters.end());
    effects::check(*e, p);
    b.terms.push_back({e, p});
  }
  return b;
}

// The baseline plus every finding: what the twin should run from now on.
ModelFile corrected_model(const ModelFile& base, const actuator::Selection& sel,
                          const std::string& recording) {
  ModelFile m = base;
  m.source = "maglead analyze of " + recording;
  for (const auto& c : sel.chosen) {
    auto& term = m.term(c.id);
    term.enabled = true;
    term.parameters.assign(c.params.begin(), c.params.end());
    term.note = "held-out gain " + fmt(c.gain_pct) + " %, t = " + fmt(c.t_stat);
  }
  return m;
}

// The missing force at the sliding samples over recording time, before and after the findings.
// Samples further apart than two decimated periods belong to different sliding stretches: a NaN
// between them keeps a plot from drawing a line across the stuck time in between.
Chart fit_over_time(const actuator::Prepared& P, const actuator::Selection& sel) {
  const bool added = !sel.chosen.empty();
  Chart c{"The fit before and after", "time [s]", "missing force [N]",
          {{added ? "before (the model as configured)" : "the model (nothing added)", {}, {}}}};
  if (added) c.curves.push_back({"after (with the effects found)", {}, {}});
  const double gap_s = 2.0 * P.decimation / P.fs_hz;
  for (std::size_t i = 0; i < P.states.size(); ++i) {
    const double t = P.states[i].t_s + P.t0_s;
    if (i > 0 && P.states[i].t_s - P.states[i - 1].t_s > gap_s)
      for (auto& curve : c.curves) curve.x.push_back(t - 0.5 * gap_s), curve.y.push_back(NAN);
    c.curves[0].x.push_back(t);
    c.curves[0].y.push_back(P.residual[i]);
    if (added) c.curves[1].x.push_back(t), c.curves[1].y.push_back(sel.final_residual[i]);
  }
  return c;
}

}  // namespace

AnalysisResult analyze_actuator(const Recording& rec, const ModelFile& model,
                                const ForceCalibration& cal, const ActuatorParams& act,
                                const AnalysisOptions& opt) {
  auto progress = [&](const std::string& stage, double f) {
    if (opt.progress) opt.progress(stage, f);
  };
  actuator::Options o;
  o.folds = opt.folds;
  if (opt.filter_hz > 0) o.filter_hz = opt.filter_hz;
  o.min_gain_pct = opt.min_gain_pct;
  o.min_t = opt.min_t;
  const auto base = baseline_of(model);
  for (const auto& t : base.terms) o.exclude.emplace_back(t.effect->id());

  progress("prepare", 0.0);
  const auto P = actuator::prepare(rec, base, cal, act, o);
  progress("prepare", 1.0);
  auto sel = actuator::select(P, o, [&](double f) { progress("selection", f); });
  progress("selection", 1.0);
  const auto bt = actuator::breakaway_test(P, base, sel.chosen);
  const auto stribeck = actuator::stribeck_from_breakaway(P, base, sel, bt, o);
  if (stribeck) {
    // Its sliding part belongs to the corrected model's error too; a kinetic level the sliding
    // fit already found is in it (and in the residual) once.
    const auto* e = effects::find(stribeck->id);
    const auto* coulomb = effects::find("coulomb_friction");
    const effects::Params kinetic{{"coulomb_n", stribeck->params.at("coulomb_n")}};
    sel.final_sse = 0;
    for (std::size_t i = 0; i < P.states.size(); ++i) {
      sel.final_residual[i] -= e->force_n(stribeck->params, P.states[i]) -
                               coulomb->force_n(kinetic, P.states[i]);
      sel.final_sse += sel.final_residual[i] * sel.final_residual[i];
    }
  }

  Json J;
  J["system"] = "actuator";
  J["recording"] = rec.path;
  J["samples"] = P.samples;
  J["samples_used"] = sel.samples_used;
  J["method"] = {
      {"domain", "force (inverse model: the force the baseline leaves out of the nut's balance, "
                 "from measured motion and load)"},
      {"filter", "4th-order Butterworth at " + fmt(P.filter_hz) + " Hz, zero phase, on every signal"},
      {"decimation", P.decimation},
      {"folds", o.folds},
      {"selection", "forward, by held-out error on contiguous time segments; a term must cut the "
                    "held-out mean square error by " + fmt(o.min_gain_pct) + " % with t >= " +
                        fmt(o.min_t) + " over the segments"},
      {"moving_only", "sliding samples only (faster than " + fmt(P.v_min_m_s * 1e3) +
                          " mm/s, one direction over the filter's support); stuck episodes feed "
                          "the break-away test"}};
  J["noise_floor_n"] = P.load_noise_n;
  const double n_used = std::max<double>(1.0, static_cast<double>(sel.samples_used));
  auto rms = [&](double s) { return std::sqrt(s / n_used); };
  auto rel = [&](double s) { return sel.measured_ss > 0 ? 100.0 * std::sqrt(s / sel.measured_ss) : 0.0; };
  J["baseline"] = {{"rms", rms(sel.baseline_sse)},
                   {"relative_error_pct", rel(sel.baseline_sse)},
                   {"full_rate", {{"rms", rms(sel.baseline_sse)}, {"relative_error_pct", rel(sel.baseline_sse)}}},
                   {"heldout_rms", rms(sel.baseline_heldout_sse)}};
  Json effects_json = Json::array();
  Json validation = Json::array();
  validation.push_back({{"model", "baseline"}, {"heldout_rms", rms(sel.baseline_heldout_sse)},
                        {"heldout_relative_error_pct", rel(sel.baseline_heldout_sse)}});
  double prev = sel.baseline_heldout_sse;
  for (std::size_t k = 0; k < sel.chosen.size(); ++k) {
    const auto& c = sel.chosen[k];
    Json e;
    e["id"] = c.id;
    e["parameters"] = params_json(c.params);
    e["evidence"] = {{"heldout_gain_pct", c.gain_pct},
                     {"t_stat", c.t_stat},
                     {"segments_improved", std::to_string(c.segments_improved) + "/" + std::to_string(c.segments)},
                     {"explained_rms_n", std::sqrt(std::max(0.0, prev - sel.heldout_sse_after[k]) / n_used)},
                     {"noise_floor_n", P.load_noise_n}};
    e["improvement_pct"] = 100.0 * (prev - sel.heldout_sse_after[k]) / sel.baseline_heldout_sse;
    e["where"] = "sliding samples";
    if (!c.alternatives.empty()) {
      Json alts = Json::array();
      for (const auto& a : c.alternatives)
        alts.push_back({{"id", a.id}, {"parameters", params_json(a.params)}, {"explains_pct", a.explains_pct}});
      e["alternatives"] = alts;
      e["finding"] = "the data cannot tell these apart here; " + c.id + " is preferred";
    }
    prev = sel.heldout_sse_after[k];
    validation.push_back({{"model", "+ " + c.id}, {"heldout_rms", rms(prev)}, {"heldout_relative_error_pct", rel(prev)}});
    effects_json.push_back(e);
  }
  if (stribeck) {
    // Stribeck's law holds the kinetic level: a coulomb_friction finding becomes part of it.
    std::erase_if(sel.chosen, [](const actuator::Candidate& c) { return c.id == "coulomb_friction"; });
    for (auto it = effects_json.begin(); it != effects_json.end(); ++it)
      if ((*it)["id"] == "coulomb_friction") {
        effects_json.erase(it);
        break;
      }
    effects_json.push_back(
        {{"id", stribeck->id},
         {"parameters", params_json(stribeck->params)},
         {"where", "stuck episodes: the nut breaks away above its sliding friction in both directions"},
         {"evidence", {{"heldout_gain_pct", nullptr},
                       {"t_stat", stribeck->t_stat},
                       {"segments_improved", std::to_string(stribeck->segments) + " releases"},
                       {"breakaway_excess_pos_n", bt.pos.median_excess_n},
                       {"breakaway_excess_neg_n", bt.neg.median_excess_n},
                       {"encoder_count_force_n", bt.pos.count_force_n}}},
         {"improvement_pct", 0.0},
         {"note", stribeck->velocity_determined
                      ? "break-away from the net force at release; the Stribeck velocity is the one "
                        "the sliding samples prefer"
                      : "break-away from the net force at release; the Stribeck velocity is not "
                        "determined (no slow sliding in the recording): the middle of the range "
                        "scanned"}});
    sel.chosen.push_back(*stribeck);
  }
  Json events = Json::array();
  for (const auto& s : P.slips)
    events.push_back({{"type", "step_out"}, {"t_s", s.t_s - P.t0_s}, {"start_s", s.start_s - P.t0_s}, {"leads", s.leads}});
  const auto pulses = actuator::find_pulses(P, sel, o);
  if (!pulses.empty()) {
    double largest = 0;
    for (const auto& q : pulses) {
      events.push_back({{"type", "external_disturbance"}, {"t_s", q.t_s}, {"duration_s", q.duration_s},
                        {"force_n", q.force_n}});
      if (std::abs(q.force_n) > std::abs(largest)) largest = q.force_n;
    }
    effects_json.push_back({{"id", "external_disturbance"},
                            {"parameters", {{"count", pulses.size()}, {"force_n", largest}}},
                            {"where", "isolated force pulses no input explains (see events)"},
                            {"evidence", {{"events", pulses.size()}, {"heldout_gain_pct", nullptr}}},
                            {"improvement_pct", 0.0}});
  }
  if (!P.slips.empty())
    effects_json.push_back({{"id", "step_out"},
                            {"parameters", {{"count", P.slips.size()}}},
                            {"where", "the phase left the stable branch and the nut slipped by whole leads"},
                            {"evidence", {{"events", P.slips.size()}, {"heldout_gain_pct", nullptr}}},
                            {"improvement_pct", 0.0}});
  J["effects"] = effects_json;
  J["events"] = events;
  J["breakaway_test"] = {{"pos", {{"episodes", bt.pos.episodes}, {"median_excess_n", bt.pos.median_excess_n}, {"se_n", bt.pos.se_n}}},
                         {"neg", {{"episodes", bt.neg.episodes}, {"median_excess_n", bt.neg.median_excess_n}, {"se_n", bt.neg.se_n}}}};
  J["validation"] = validation;
  J["final"] = {{"rms", rms(sel.final_sse)},
                {"relative_error_pct", rel(sel.final_sse)},
                {"full_rate", {{"rms", rms(sel.final_sse)}, {"relative_error_pct", rel(sel.final_sse)}}}};
  J["not_selected"] = Json::array();
  if (!sel.next_best.id.empty())
    J["not_selected"].push_back({{"id", sel.next_best.id}, {"heldout_gain_pct", sel.next_best.gain_pct},
                                 {"t_stat", sel.next_best.t_stat}, {"parameters", params_json(sel.next_best.params)}});
  J["where"] = Json::array();
  J["conclusion"] = sel.chosen.empty() ? "nothing is missing: no effect explains a significant part of "
                                          "the held-out error"
                                        : std::to_string(sel.chosen.size()) + " effect(s) found";
  AnalysisResult r;
  r.json = J;
  r.corrected = corrected_model(model, sel, rec.path);
  r.fit_over_time = fit_over_time(P, sel);
  return r;
}

}  // namespace maglead::analysis
