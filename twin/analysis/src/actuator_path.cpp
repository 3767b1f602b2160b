// The actuator's path of the analysis (path.hpp): runs the stages of actuator_analysis.cpp and
// turns their typed results into the analysis result (findings, corrected model, figures).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <future>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "actuator_analysis.hpp"
#include "actuator_twin_force.hpp"
#include "maglead/analysis/analysis.hpp"
#include "path.hpp"
#include "statistics.hpp"

namespace maglead::analysis {
namespace {

using selection::parameters_of;
using stats::ErrorScale;  // over the sliding samples used

// Numbers in the findings' words: three significant digits.
std::string fmt3(double v) { return number_text(v, 3); }

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

// "; replaces [model] viscous_n_s_per_m = 2 while enabled" for a parameter that is a [model]
// value's whole (the term's value is the total, not an addition): a reader of the file cannot
// tell otherwise.
std::string replaces_text(const ModelFile& base, const std::string& name) {
  const std::pair<const char*, double> keys[] = {{"nut_mass_kg", base.nut_mass_kg},
                                                 {"viscous_n_s_per_m", base.viscous_n_s_per_m},
                                                 {"coulomb_n", base.coulomb_n}};
  for (const auto& [key, value] : keys)
    if (name == key) {
      char b[96];
      std::snprintf(b, sizeof b, "; replaces [model] %s = %g while enabled", key, value);
      return b;
    }
  return "";
}

// The baseline plus the findings given: what the twin should run from now on.
ModelFile model_with(const ModelFile& base, const std::vector<selection::Found>& terms,
                     const std::string& recording) {
  ModelFile m = base;
  m.source = "maglead analyze of " + recording;
  for (const auto& c : terms) {
    auto& term = m.term(c.id);
    term.enabled = true;
    term.parameters.assign(c.params.begin(), c.params.end());
    // The finding as analyze prints it: values with their errors, the evidence, and what the
    // data could not decide.
    char evidence[96];
    std::snprintf(evidence, sizeof evidence, "; held-out gain %.2f %%, t = %.1f", c.gain_pct,
                  c.t_stat);
    term.note = summary_text(parameters_of(c.params), parameters_of(c.standard_errors)) + evidence;
    for (const auto& p : c.params) term.note += replaces_text(base, p.first);
    for (const auto& a : c.alternatives)
      if (a.plausible) {
        std::snprintf(evidence, sizeof evidence, "%.2f", a.explains_pct);
        term.note += "; the data cannot tell it from " + a.id + " (which reproduces " +
                     std::string(evidence) + " % of it)";
      }
  }
  return m;
}

// The missing force at the sliding samples over recording time, before and after the findings.
// Samples further apart than two decimated periods belong to different sliding stretches: a NaN
// between them keeps a plot from drawing a line across the stuck time in between.
Chart fit_over_time(const actuator::ActuatorPrepared& P, const actuator::SlidingSelection& sel) {
  const bool added = !sel.terms.empty();
  Chart c{"The fit before and after",
          "time [s]",
          "missing force [N]",
          {{added ? "before (the model as configured)" : "the model (nothing added)", {}, {}}}};
  if (added) c.curves.push_back({"after (with the effects found)", {}, {}});
  // A gap of more than two kept samples ends a stretch of sliding samples (the chart breaks).
  constexpr double kGapSamples = 2.0;
  const double gap_s = kGapSamples * P.decimation / P.fs_hz;
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

// A term leaves the corrected model only when the twin's force estimate gets worse with it beyond
// the noise of that difference and beyond the force the recording resolves
// (actuator::rises_beyond_noise over the scored blocks): terms join in the order they were found. A
// term left out stays in the file, disabled, with the reason. `corrected` becomes the model of the
// kept terms; `why` the reason for each dropped one.
TwinForceCheck check_with_twin(const Recording& rec, const ActuatorParams& act,
                               const ForceCalibration& cal, double resolved_n,
                               const ModelFile& base, const std::vector<selection::Found>& terms,
                               ModelFile& corrected, std::vector<std::string>& why) {
  TwinForceCheck out;
  // The configured and the corrected model's runs are independent (each its own twin): side by
  // side they take the time of one.
  auto corrected_run = std::async(std::launch::async, [&] {
    return terms.empty() ? std::nullopt : actuator::twin_force_errors(rec, act, cal, corrected);
  });
  const auto before = actuator::twin_force_errors(rec, act, cal, base);
  const auto all = corrected_run.get();
  if (!before) {
    out.reason = "maglead_twin (SUNDIALS) not built";
    return out;
  }
  out.available = true;
  out.resolved_n = resolved_n;
  out.baseline_mae_n = out.corrected_mae_n = before->mae_n;
  if (terms.empty()) return out;
  if (all && !actuator::rises_beyond_noise(*all, *before, resolved_n)) {  // the usual case
    out.corrected_mae_n = all->mae_n;
    for (const auto& c : terms) out.kept.push_back(c.id);
    return out;
  }
  std::vector<selection::Found> kept;
  actuator::TwinForceErrors current = *before;
  for (const auto& c : terms) {
    auto trial = kept;
    trial.push_back(c);
    const auto err = actuator::twin_force_errors(rec, act, cal, model_with(base, trial, rec.path));
    if (err && !actuator::rises_beyond_noise(*err, current, resolved_n)) {
      kept = std::move(trial);
      current = *err;
      out.kept.push_back(c.id);
    } else {
      out.dropped.push_back(c.id);
      why.push_back("with it the twin's force error rose beyond its noise: " + fmt3(current.mae_n) +
                    " -> " + fmt3(err ? err->mae_n : NAN) + " N");
    }
  }
  out.corrected_mae_n = current.mae_n;
  corrected = model_with(base, kept, rec.path);
  for (std::size_t k = 0; k < out.dropped.size(); ++k)
    for (const auto& c : terms)
      if (c.id == out.dropped[k]) {
        auto& term = corrected.term(c.id);
        term.enabled = false;
        term.parameters.assign(c.params.begin(), c.params.end());
        term.note = "disabled: " + why[k];
      }
  return out;
}

// "; a calibration error within the minimum moves viscous_n_s_per_m by up to 3.6 N·s/m" (empty:
// none).
std::string calibration_text(const effects::Params& errors) {
  std::string s;
  for (const auto& [name, error] : errors)
    s += (s.empty() ? "" : ", ") + name + " by up to " + calibration_bound_text(name, error);
  return s.empty() ? s : "; a calibration error within the minimum moves " + s;
}

std::string summary_of(const selection::Found& c, const actuator::ActuatorPrepared& P) {
  const std::string s = summary_text(parameters_of(c.params), parameters_of(c.standard_errors)) +
                        calibration_text(c.calibration_errors);
  char buf[224];
  if (P.locked_share > 0)
    std::snprintf(buf, sizeof buf,
                  " (floor %.3f N resolved, %.3f N where the count is locked to the sample clock "
                  "(%.0f %% of the sliding samples), minimum %.3f N)",
                  P.floor_n, P.locked_floor_n, 100.0 * P.locked_share, P.minimum_n);
  else
    std::snprintf(buf, sizeof buf, " (floor %.3f N resolved, minimum %.3f N)", P.floor_n,
                  P.minimum_n);
  return s + buf;
}

std::optional<Unexplained> actuator_unexplained(const actuator::SlidingSelection& sel) {
  if (!sel.implausible) return std::nullopt;
  return selection::unexplained_of(
      *sel.implausible,
      "units and sign of load_force_n, the calibration (is it this actuator's?), the encoder "
      "scales (lead, counts) and the load cell itself");
}

actuator::StageOptions options_of(const AnalysisOptions& opt, const actuator::Baseline& base) {
  actuator::StageOptions o;
  o.folds = opt.folds;
  if (opt.filter_hz > 0) o.filter_hz = opt.filter_hz;
  o.min_gain_pct = opt.min_gain_pct;
  o.min_t = opt.min_t;
  o.calibration_accuracy_n = opt.actuator.calibration_accuracy_n;
  for (const auto& t : base.terms) o.exclude.emplace_back(t.effect->id());
  return o;
}

// Stribeck's sliding part belongs to the corrected model's error too; a kinetic level the sliding
// fit already found is in it (and in the residual) once.
void fold_in_stribeck(actuator::SlidingSelection& sel, const actuator::ActuatorPrepared& P,
                      const selection::Found& stribeck) {
  const auto* e = effects::find(stribeck.id);
  const auto* coulomb = effects::find("coulomb_friction");
  const effects::Params kinetic{{"coulomb_n", stribeck.params.at("coulomb_n")}};
  sel.final_sse = 0;
  for (std::size_t i = 0; i < P.states.size(); ++i) {
    sel.final_residual[i] -=
        e->force_n(stribeck.params, P.states[i]) - coulomb->force_n(kinetic, P.states[i]);
    sel.final_sse += sel.final_residual[i] * sel.final_residual[i];
  }
}

// Stribeck's law holds the kinetic level (its parameters are breakaway_n, coulomb_n and v_s): a
// Coulomb level the sliding fit took beside a hump it also took is that law's F_c, one finding,
// not a second effect. The force is the same: the hump's column is its excess over the baseline's
// level, so the break-away moves with the level.
void kinetic_level_into_stribeck(actuator::SlidingSelection& sel) {
  auto& terms = sel.terms;
  const auto named = [&](std::string_view id) {
    return std::find_if(terms.begin(), terms.end(), [&](const auto& c) { return c.id == id; });
  };
  const auto stribeck = named("stribeck_friction"), coulomb = named("coulomb_friction");
  if (stribeck == terms.end() || coulomb == terms.end()) return;
  const double level_n = coulomb->params.at("coulomb_n");
  stribeck->params["breakaway_n"] += level_n - stribeck->params.at("coulomb_n");
  stribeck->params["coulomb_n"] = level_n;
  auto& se = stribeck->standard_errors;
  const double level_se = coulomb->standard_errors.count("coulomb_n") > 0
                              ? coulomb->standard_errors.at("coulomb_n")
                              : 0.0;
  if (se.count("breakaway_n") > 0) se["breakaway_n"] = std::hypot(se["breakaway_n"], level_se);
  se["coulomb_n"] = level_se;
  stribeck->idx.insert(stribeck->idx.end(), coulomb->idx.begin(), coulomb->idx.end());
  terms.erase(coulomb);
}

// An offset from the releases acts on the sliding samples too (the few there are).
void fold_in_offset(actuator::SlidingSelection& sel, const actuator::ActuatorPrepared& P,
                    const selection::Found& offset) {
  sel.final_sse = 0;
  for (std::size_t i = 0; i < P.states.size(); ++i) {
    sel.final_residual[i] -= offset.effect->force_n(offset.params, P.states[i]);
    sel.final_sse += sel.final_residual[i] * sel.final_residual[i];
  }
}

Method method_of(const actuator::ActuatorPrepared& P, const actuator::StageOptions& o) {
  Method m;
  m.domain =
      "force (inverse model: the force the baseline leaves out of the nut's balance, "
      "from measured motion and load)";
  m.filter = "4th-order Butterworth at " + fmt3(P.filter_hz) + " Hz, zero phase, on every signal";
  m.decimation = P.decimation;
  m.folds = std::max(rules::kMinFolds, o.folds);  // as select_sliding uses them
  m.selection = actuator::selection_rule(o);
  m.moving_only = "sliding samples only (faster than " + fmt3(P.v_min_m_s * 1e3) +
                  " mm/s, one direction over the filter's support); stuck episodes feed "
                  "the break-away test";
  return m;
}

EffectFinding sliding_finding(const selection::Found& c, const actuator::ActuatorPrepared& P,
                              const ErrorScale& es) {
  const double sse_before = c.heldout_before, sse_after = c.heldout_after;
  EffectFinding e;
  e.id = c.id;
  e.parameters = parameters_of(c.params);
  e.evidence.heldout_gain_pct = c.gain_pct;
  e.evidence.t_stat = c.t_stat;
  e.evidence.segments_improved =
      std::to_string(c.segments_improved) + "/" + std::to_string(c.segments);
  e.evidence.explained_rms_n = es.rms(std::max(0.0, sse_before - sse_after));
  e.evidence.noise_floor_n = P.load_noise_n;
  e.evidence.resolution_floor_n = P.floor_n;
  e.evidence.minimum_n = P.minimum_n;
  e.standard_errors = stated_errors(e.parameters, parameters_of(c.standard_errors));
  e.calibration_errors = parameters_of(c.calibration_errors);
  e.summary = summary_of(c, P);
  if (c.acting_share < 1.0) {
    e.evidence.acting_share_pct = 100.0 * c.acting_share;
    char buf[128];
    std::snprintf(buf, sizeof buf, "; it acts on %.0f %% of the sliding samples, %.3f N RMS there",
                  100.0 * c.acting_share, *e.evidence.explained_rms_n / std::sqrt(c.acting_share));
    e.summary += buf;
  }
  e.improvement_pct = c.improvement_pct;
  e.where = "sliding samples";
  // Only the plausible alternatives: one outside its physical range explains nothing here.
  for (const auto& a : c.alternatives)
    if (a.plausible)
      e.alternatives.push_back({a.id, parameters_of(*a.params), a.explains_pct, std::nullopt});
  if (!e.alternatives.empty()) {
    std::string others;  // "a", "a or b", "a, b or c"
    for (std::size_t k = 0; k < e.alternatives.size(); ++k)
      others += (k == 0                           ? ""
                 : k + 1 == e.alternatives.size() ? " or "
                                                  : ", ") +
                e.alternatives[k].id;
    e.finding = "the data cannot tell " + c.id + " from " + others + " here; " + c.id +
                " is preferred (alternatives below)";
  }
  return e;
}

// The terms the sliding fit chose, and the validation: each term taken or dropped.
void add_sliding_findings(Findings& J, const actuator::SlidingSelection& sel,
                          const actuator::ActuatorPrepared& P, const ErrorScale& es) {
  J.validation.push_back({"baseline", es.rms(sel.start_heldout_sse), es.rel(sel.start_heldout_sse),
                          std::nullopt, std::nullopt});
  for (const auto& c : sel.terms) J.effects.push_back(sliding_finding(c, P, es));
  for (const auto& st : sel.steps)
    J.validation.push_back(
        {st.model, es.rms(st.heldout_sse), es.rel(st.heldout_sse), std::nullopt, std::nullopt});
}

// A finding read from the releases (the break-away test), with them as its evidence.
EffectFinding release_finding(const selection::Found& c, const actuator::Breakaway& bt,
                              std::string where) {
  EffectFinding e;
  e.id = c.id;
  e.parameters = parameters_of(c.params);
  e.where = std::move(where);
  e.evidence.t_stat = c.t_stat;
  e.evidence.segments_improved = std::to_string(c.segments) + " releases";
  e.evidence.breakaway_excess_pos_n = bt.pos.median_excess_n;
  e.evidence.breakaway_excess_neg_n = bt.neg.median_excess_n;
  e.evidence.encoder_count_force_n = bt.pos.count_force_n;
  return e;
}

EffectFinding stribeck_finding(const selection::Found& stribeck, const actuator::Breakaway& bt,
                               const actuator::ActuatorPrepared& P) {
  auto e = release_finding(
      stribeck, bt,
      "stuck episodes: the nut breaks away above its sliding friction in both directions");
  // The break-away's error: the two sides' medians averaged.
  auto c = stribeck;
  c.standard_errors["breakaway_n"] = 0.5 * std::hypot(bt.pos.se_n, bt.neg.se_n);
  e.standard_errors = stated_errors(e.parameters, parameters_of(c.standard_errors));
  // The break-away is the coupling's force at release: a coupling error within the calibration's
  // accuracy moves it by as much, in every release alike (no standard error sees it).
  c.calibration_errors = {{"breakaway_n", P.minimum_n}};
  e.calibration_errors = parameters_of(c.calibration_errors);
  e.summary = summary_of(c, P);
  e.improvement_pct = 0.0;
  const auto releases = stribeck.from_releases.value_or(selection::Found::FromReleases{});
  const auto [vs_low, vs_high] = releases.velocity_range_m_s;
  e.note = releases.velocity_determined
               ? "break-away from the net force at release; the Stribeck velocity is the one "
                 "the sliding samples prefer"
               : "break-away from the net force at release; the Stribeck velocity is not "
                 "determined (the sliding samples fit every value from " +
                     fmt3(vs_low) + " to " + fmt3(vs_high) +
                     " m/s alike: too little slow sliding): the middle of those";
  e.note +=
      "; the force read at release is corrected for what rose while the nut crossed "
      "its first count (" +
      fmt3(0.5 * (bt.pos.lag_expected_n + bt.neg.lag_expected_n)) + " N, at most " +
      fmt3(std::max(bt.pos.lag_bound_n, bt.neg.lag_bound_n)) + " N)";
  if (releases.stops_left_out > 0)
    e.note += "; the sliding fit leaves out the samples within the filter's reach of " +
              std::to_string(releases.stops_left_out) +
              " stops its filtered speed hides (stick-slip: no friction law of the speed holds "
              "at a speed that averages stuck and slipping motion)";
  return e;
}

// Stribeck's law holds the kinetic level: a coulomb_friction finding becomes part of it.
void add_stribeck(Findings& J, actuator::SlidingSelection& sel, const selection::Found& stribeck,
                  const actuator::Breakaway& bt, const actuator::ActuatorPrepared& P) {
  std::erase_if(sel.terms, [](const selection::Found& c) { return c.id == "coulomb_friction"; });
  for (auto it = J.effects.begin(); it != J.effects.end(); ++it)
    if (it->id == "coulomb_friction") {
      J.effects.erase(it);
      break;
    }
  J.effects.push_back(stribeck_finding(stribeck, bt, P));
  sel.terms.push_back(stribeck);
}

// An offset the releases show where the nut barely slides (actuator::offset_from_breakaway): a
// term of the corrected model like a sliding finding, with the releases as its evidence.
void add_offset(Findings& J, actuator::SlidingSelection& sel, const selection::Found& offset,
                const actuator::Breakaway& bt, const actuator::ActuatorPrepared& P) {
  auto e = release_finding(
      offset, bt, "stuck episodes: the nut breaks away at levels that differ by direction");
  e.evidence.resolution_floor_n = P.floor_n;
  e.evidence.minimum_n = P.minimum_n;
  e.standard_errors = stated_errors(e.parameters, parameters_of(offset.standard_errors));
  e.summary = summary_of(offset, P);
  // At rest only the break-away is seen: friction lower by F_o in +p and higher in −p is the same.
  e.alternatives.push_back({"asymmetric_friction", {}, 100.0, std::nullopt});
  e.identifiable = false;
  e.note =
      "from the releases alone (half the difference of the break-away read in −p and +p): "
      "direction-dependent friction differing by twice as much reads the same at rest";
  J.effects.push_back(std::move(e));
  sel.terms.push_back(offset);
}

void add_step_outs(Findings& J, const actuator::ActuatorPrepared& P) {
  for (const auto& s : P.slips) {
    Event ev;
    ev.type = "step_out";
    ev.t_s = s.t_s - P.t0_s;
    ev.start_s = s.start_s - P.t0_s;
    ev.leads = s.leads;
    J.events.push_back(ev);
  }
}

void add_step_out_finding(Findings& J, const actuator::ActuatorPrepared& P) {
  if (P.slips.empty()) return;
  EffectFinding e;
  e.id = "step_out";
  set_parameter(e.parameters, "count", static_cast<double>(P.slips.size()), true);
  e.where = "the phase left the stable branch and the nut slipped by whole leads";
  e.evidence.events = P.slips.size();
  J.effects.push_back(e);
}

// A recording that barely slides says so, and what it can still tell (empty: it slides enough).
std::string sliding_note(const actuator::ActuatorPrepared& P,
                         const actuator::SlidingSelection& sel) {
  // Sliding samples are counted after decimation; the recording's samples before.
  const std::size_t sliding = sel.samples_used * static_cast<std::size_t>(P.decimation);
  if (!sel.too_little_sliding && sliding >= P.samples / rules::kBarelySlidesOneIn) return {};
  std::string head = "the nut barely slides (" + std::to_string(sliding) + " sliding samples of " +
                     std::to_string(P.samples) + "): the sliding fit says little; ";
  // Sliding starts at one encoder count per filter period: a filter raised above the default
  // raises that speed, and a slow recording (a hand push at 1 mm/s) then has none. That is the
  // option's doing, not the recording's: say which option and what the default counts.
  const double default_hz = std::min(rules::kFilterHz, rules::kFilterMaxOfRate * P.fs_hz);
  if (P.filter_hz > default_hz)
    head = "too few samples slide faster than " + fmt3(P.v_min_m_s * 1e3) + " mm/s (" +
           std::to_string(sliding) + " of " + std::to_string(P.samples) +
           "), the speed --filter-hz " + fmt3(P.filter_hz) +
           " sets (one encoder count per filter period); the default " + fmt3(default_hz) +
           " Hz counts sliding from " + fmt3(P.count_m * default_hz * 1e3) +
           " mm/s: leave --filter-hz out or lower it. The sliding fit says little; ";
  if (P.stuck.empty())  // nothing released either: the stands tell nothing
    return head +
           "no stand ended in a release, so neither the break-away friction nor an offset "
           "can be told; events (step-outs, pulses) are still looked for";
  return head + "the stuck episodes (" + std::to_string(P.stuck.size()) +
         " releases) still tell the break-away friction and, from how it differs by direction, "
         "an offset; events (step-outs, pulses) are still found";
}

// Candidates the findings list as not selected beside the selection's own.
struct LeftOut {
  const std::vector<Rejected>& rejected;  // taken, then refused (sliding_fit)
  const std::vector<Rejected>& unjudged;  // laws the recording cannot judge at all
};

// What the releases name beside the sliding fit (ActuatorPath::select), and their test.
struct ReleaseFindings {
  const std::optional<selection::Found>& stribeck;
  const std::optional<selection::Found>& offset;
  const actuator::Breakaway& bt;
};

// With the nut sliding one way, friction, an offset and a coupling gain differ by nothing the
// recording shows (they differ by the direction of travel): a term with many alternatives that
// fit alike names no law there, and the conclusion says so first, not "found".
void one_way_unjudged(Findings& J, const actuator::ActuatorPrepared& P) {
  std::size_t up = 0, down = 0;
  for (const auto& st : P.states) {
    if (st.v_m_s > 0) ++up;
    if (st.v_m_s < 0) ++down;
  }
  const std::size_t sliding = up + down, other = std::min(up, down);
  if (sliding == 0 ||
      static_cast<double>(other) >= rules::kOneWayOtherShare * static_cast<double>(sliding))
    return;
  for (const auto& e : J.effects) {
    if (e.evidence.events || e.alternatives.size() < rules::kOneWayAlikeAlternatives) continue;
    std::string laws = e.id;
    for (std::size_t k = 0; k < e.alternatives.size(); ++k)
      laws += (k + 1 == e.alternatives.size() ? " or " : ", ") + e.alternatives[k].id;
    J.conclusion = std::string(kNotJudged) + "the nut slides in one direction of travel only (" +
                   std::to_string(other) + " of " + std::to_string(sliding) +
                   " sliding samples the other way), where laws that differ by the direction "
                   "fit alike; " +
                   std::to_string(e.alternatives.size() + 1) + " laws fit alike here (" + laws +
                   "); record moves both ways to tell them apart (the corrected model takes " +
                   e.id + " as one of them)";
    J.nothing_missing = std::nullopt;
    return;
  }
}

// The typed findings of the stages' results.
Findings findings_of(const Recording& rec, const actuator::ActuatorPrepared& P,
                     actuator::SlidingSelection& sel, const LeftOut& left_out,
                     const ReleaseFindings& releases, const actuator::StageOptions& o) {
  const actuator::Breakaway& bt = releases.bt;
  Findings J;
  J.system = "actuator";
  J.recording = rec.path;
  J.samples = P.samples;
  J.samples_used = sel.samples_used;
  J.method = method_of(P, o);
  J.noise_floor_n = P.load_noise_n;
  J.noise_step_n = P.load_noise_step_n;
  const ErrorScale es{std::max<double>(1.0, static_cast<double>(sel.samples_used)),
                      sel.measured_ss};
  J.baseline = {es.rms(sel.baseline_sse),
                es.rel(sel.baseline_sse),
                es.rms(sel.baseline_sse),
                es.rel(sel.baseline_sse),
                es.rms(sel.start_heldout_sse),
                std::nullopt,
                {},
                {}};
  add_sliding_findings(J, sel, P, es);
  if (releases.stribeck) add_stribeck(J, sel, *releases.stribeck, bt, P);
  if (releases.offset) add_offset(J, sel, *releases.offset, bt, P);
  add_step_outs(J, P);
  pulses::report(J, actuator::actuator_pulses(P, sel, o));
  add_step_out_finding(J, P);
  J.breakaway_test = BreakawayTest{{bt.pos.episodes, bt.pos.median_excess_n, bt.pos.se_n},
                                   {bt.neg.episodes, bt.neg.median_excess_n, bt.neg.se_n}};
  J.final_fit = {es.rms(sel.final_sse),
                 es.rel(sel.final_sse),
                 es.rms(sel.final_sse),
                 es.rel(sel.final_sse),
                 std::nullopt,
                 std::nullopt,
                 {},
                 {}};
  if (sel.stopped_at)
    J.not_selected.push_back(selection::best_left_out(*sel.stopped_at, sel.stopped_reason));
  J.not_selected.insert(J.not_selected.end(), sel.dropped.begin(), sel.dropped.end());
  J.not_selected.insert(J.not_selected.begin(), left_out.rejected.begin(), left_out.rejected.end());
  J.not_selected.insert(J.not_selected.end(), left_out.unjudged.begin(), left_out.unjudged.end());
  J.unexplained = actuator_unexplained(sel);
  J.sliding_note = sliding_note(P, sel);
  J.resolvable = sel.resolvable;
  conclude(J, {.terms_named = sel.terms.size(),
               .implausible = sel.implausible.has_value(),
               // Each size is one effect's alone: two changes together can cancel in the force.
               .unresolved = J.resolvable.empty() ? ""
                                                  : "; it cannot name changes smaller than (each "
                                                    "effect alone; two can cancel): " +
                                                        resolvable_text(J.resolvable),
               .check = "the calibration, the sensors' timing and loads the recording does not "
                        "log",
               .kind = &effects::linear_axis()});
  // Too little sliding for the selection to run, and nothing named from the stands or events:
  // that is not judged, never "nothing is missing". Counted in the recording's samples, as the
  // sliding note counts them (the fit's are after decimation).
  if (J.effects.empty() && !J.unexplained && sel.too_little_sliding) {
    const auto decimation = static_cast<std::size_t>(P.decimation);
    J.conclusion = std::string(kNotJudged) + "too little sliding to judge the model (" +
                   std::to_string(J.samples_used * decimation) + " sliding samples of " +
                   std::to_string(J.samples) + ", the fit needs " +
                   std::to_string(rules::kMinSlidingSamples * decimation) + ")";
    J.nothing_missing = std::nullopt;
  }
  one_way_unjudged(J, P);
  return J;
}

struct SlidingFit {
  actuator::SlidingSelection fit;
  std::vector<Rejected> rejected;  // terms taken, then refused (unseen hump, implausible)
};

Rejected refused(const selection::Found& c, const std::string& why) {
  return Rejected{
      c.id, c.gain_pct, c.t_stat, std::nullopt, std::nullopt, why, parameters_of(c.params)};
}

// The forward selection on the sliding samples; a Stribeck term it takes that the releases do
// not show is rejected and the others chosen again without it. That and the terms the
// selection refused in the final fit stay out of `o`.
SlidingFit sliding_fit(const actuator::ActuatorPrepared& P, const actuator::Baseline& base,
                       actuator::StageOptions& o,
                       const std::function<void(const std::string&, double)>& progress) {
  SlidingFit out;
  const auto report = [&](double f) {
    if (progress) progress("selection", f);
  };
  out.fit = actuator::select_sliding(P, o, report);
  if (auto why = actuator::stribeck_unseen_at_rest(P, base, out.fit, o)) {
    for (const auto& c : out.fit.terms)
      if (c.id == "stribeck_friction") out.rejected.push_back(refused(c, *why));
    o.exclude.emplace_back("stribeck_friction");
    out.fit = actuator::select_sliding(P, o, report);
  }
  for (const auto& r : out.fit.refused) o.exclude.push_back(r.id);
  out.rejected.insert(out.rejected.end(), out.fit.refused.begin(), out.fit.refused.end());
  return out;
}

class ActuatorPath final : public AnalysisPath {
 public:
  ActuatorPath(const Recording& rec, const ModelFile& model, const ForceCalibration& cal,
               const ActuatorParams& act, const AnalysisOptions& opt)
      : rec_(rec),
        model_(model),
        cal_(cal),
        act_(act),
        opt_(opt),
        base_(baseline_of(model)),
        o_(options_of(opt, base_)) {}

  void prepare() override {
    P_ = actuator::prepare_actuator(rec_, base_, cal_, act_, o_);
    // Laws this recording cannot judge (too slow a rate for them) are not offered; said why.
    for (const effects::Effect* e : effects::library())
      if (auto why = e->unjudged_at(P_.scales)) {
        o_.exclude.emplace_back(e->id());
        unjudged_.push_back(Rejected{std::string(e->id()), 0.0, 0.0, {}, {}, *why, {}});
      }
  }

  void select() override;

  Findings findings() override {
    return findings_of(rec_, P_, sel_.fit, {sel_.rejected, unjudged_}, {stribeck_, offset_, bt_},
                       o_);
  }

  void figures(AnalysisResult& r) override { r.fit_over_time = fit_over_time(P_, sel_.fit); }

  void corrected_model(AnalysisResult& r) override;

 private:
  const Recording& rec_;
  const ModelFile& model_;
  const ForceCalibration& cal_;
  const ActuatorParams& act_;
  const AnalysisOptions& opt_;
  actuator::Baseline base_;
  actuator::StageOptions o_;
  actuator::ActuatorPrepared P_;
  std::vector<Rejected> unjudged_;
  SlidingFit sel_;
  actuator::Breakaway bt_;
  std::optional<selection::Found> stribeck_, offset_;
};

void ActuatorPath::select() {
  sel_ = sliding_fit(P_, base_, o_, opt_.progress);
  bt_ = actuator::breakaway_test(P_, base_, sel_.fit.terms);
  stribeck_ = actuator::stribeck_from_breakaway(P_, base_, sel_.fit, bt_, o_);
  // Break-away friction: a release is a jump (the friction drops from F_s to F_c at once), many
  // within one filter period where the nut stick-slips, and the filtered speed averages stuck and
  // slipping motion, where no friction law of the speed holds (the slips' accelerations would
  // read as mass). The sliding fit is made again without the samples those stops reach, kept if
  // the break-away test on it still names the hump. Without a hump a release is gentle and those
  // samples stay: a pulse that stalls the nut is seen there. (They are set aside in place, not
  // copied, and put back when the refit does not hold.)
  if (stribeck_) {
    const auto aside = actuator::take_stops(P_);
    bool kept = false;
    if (!aside.at.empty()) {
      auto o2 = o_;
      auto sel2 = sliding_fit(P_, base_, o2, opt_.progress);
      const auto bt2 = actuator::breakaway_test(P_, base_, sel2.fit.terms);
      if (auto s2 = actuator::stribeck_from_breakaway(P_, base_, sel2.fit, bt2, o2)) {
        sel_ = std::move(sel2), bt_ = bt2, stribeck_ = s2, o_ = std::move(o2), kept = true;
        stribeck_->from_releases->stops_left_out = P_.stops.size();
      }
    }
    if (!kept) actuator::put_back(P_, aside);
  }
  kinetic_level_into_stribeck(sel_.fit);
  if (stribeck_) fold_in_stribeck(sel_.fit, P_, *stribeck_);
  offset_ = actuator::offset_from_breakaway(P_, sel_.fit, bt_, o_);
  if (offset_) fold_in_offset(sel_.fit, P_, *offset_);
}

void ActuatorPath::corrected_model(AnalysisResult& r) {
  r.corrected = model_with(model_, sel_.fit.terms, rec_.path);
  if (!opt_.actuator.twin_force_check) return;
  std::vector<std::string> why;
  r.findings.twin_force_check =
      check_with_twin(rec_, act_, cal_, P_.floor_n, model_, sel_.fit.terms, r.corrected, why);
  const auto& dropped = r.findings.twin_force_check->dropped;
  for (auto& e : r.findings.effects)
    for (std::size_t k = 0; k < dropped.size(); ++k)
      if (e.id == dropped[k])
        e.note += std::string(e.note.empty() ? "" : "; ") +
                  "left out of model_corrected.toml (there disabled): " + why[k];
}

}  // namespace

ModelFile actuator_model_from_config(const ActuatorParams& act) {
  ModelFile m;
  m.system = "actuator";
  m.source = "config/actuator.toml (paper model)";
  m.nut_mass_kg = act.nut_mass_kg;
  m.viscous_n_s_per_m = act.viscous_n_s_per_m;
  m.coulomb_n = act.coulomb_n;
  return m;
}

std::unique_ptr<AnalysisPath> actuator_path(const Recording& rec, const ModelFile& baseline,
                                            const ForceCalibration& cal, const ActuatorParams& act,
                                            const AnalysisOptions& options) {
  return std::make_unique<ActuatorPath>(rec, baseline, cal, act, options);
}

}  // namespace maglead::analysis
