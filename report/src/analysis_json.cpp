// analysis.json written from the typed results: the layout the analysis wrote itself before
// its results were typed (same keys, same number types, same order of arrays).
#include "maglead/report/analysis_json.hpp"

#include <cstddef>

namespace maglead::report {
namespace {

using Json = nlohmann::json;
using namespace analysis;

template <class T>
void put(Json& j, const char* key, const std::optional<T>& v) {
  if (v) j[key] = *v;
}

Json evidence_json(const Evidence& e) {
  Json j;
  j["heldout_gain_pct"] = e.heldout_gain_pct ? Json(*e.heldout_gain_pct) : Json(nullptr);
  put(j, "t_stat", e.t_stat);
  put(j, "segments_improved", e.segments_improved);
  put(j, "explained_rms_n", e.explained_rms_n);
  put(j, "worst_segment_pct", e.worst_segment_pct);
  put(j, "noise_floor_n", e.noise_floor_n);
  put(j, "plausible", e.plausible);
  put(j, "breakaway_excess_pos_n", e.breakaway_excess_pos_n);
  put(j, "breakaway_excess_neg_n", e.breakaway_excess_neg_n);
  put(j, "encoder_count_force_n", e.encoder_count_force_n);
  put(j, "events", e.events);
  put(j, "resolution_floor_n", e.resolution_floor_n);
  put(j, "minimum_n", e.minimum_n);
  put(j, "acting_share_pct", e.acting_share_pct);
  return j;
}

Json effect_json(const EffectFinding& e) {
  Json j;
  j["id"] = e.id;
  j["parameters"] = parameters_json(e.parameters);
  j["where"] = e.where;
  j["evidence"] = evidence_json(e.evidence);
  j["improvement_pct"] = e.improvement_pct;
  put(j, "identifiable", e.identifiable);
  if (!e.alternatives.empty()) {
    Json alts = Json::array();
    for (const auto& a : e.alternatives) {
      Json aj{{"id", a.id},
              {"parameters", parameters_json(a.parameters)},
              {"explains_pct", a.explains_pct}};
      put(aj, "plausible", a.plausible);
      alts.push_back(aj);
    }
    j["alternatives"] = alts;
  }
  if (!e.finding.empty()) j["finding"] = e.finding;
  if (!e.note.empty()) j["note"] = e.note;
  if (!e.standard_errors.empty()) j["standard_errors"] = parameters_json(e.standard_errors);
  if (!e.calibration_errors.empty())
    j["calibration_errors"] = parameters_json(e.calibration_errors);
  if (!e.summary.empty()) j["summary"] = e.summary;
  return j;
}

Json errors_json(const FitErrors& e) {
  Json j{{"rms", e.rms_n},
         {"relative_error_pct", e.relative_error_pct},
         {"full_rate",
          {{"rms", e.full_rate_rms_n}, {"relative_error_pct", e.full_rate_relative_error_pct}}}};
  put(j, "heldout_rms", e.heldout_rms_n);
  if (e.fitted_parameters) j["fitted_parameters"] = parameters_json(*e.fitted_parameters);
  if (!e.standard_errors.empty()) j["standard_errors"] = parameters_json(e.standard_errors);
  if (!e.summary.empty()) j["summary"] = e.summary;
  return j;
}

Json event_json(const Event& e) {
  Json j{{"type", e.type}, {"t_s", e.t_s}};
  put(j, "start_s", e.start_s);
  put(j, "leads", e.leads);
  put(j, "duration_s", e.duration_s);
  put(j, "force_n", e.force_n);
  put(j, "rms_n", e.rms_n);
  return j;
}

Json twin_json(const TwinSimulation& t) {
  if (!t.available) return {{"available", false}, {"reason", t.reason}};
  return {{"available", true},
          {"integrator", t.integrator},
          {"horizon_s", t.horizon_s},
          {"windows", t.windows},
          {"baseline_rms_position_error_m", t.baseline_rms_position_error_m},
          {"corrected_rms_position_error_m", t.corrected_rms_position_error_m},
          {"baseline_failures", t.baseline_failures},
          {"corrected_failures", t.corrected_failures},
          {"steps", t.steps},
          {"root_events", t.root_events}};
}

Json resolvable_json(const std::vector<Resolvable>& resolvable) {
  Json list = Json::array();
  for (const auto& x : resolvable)
    list.push_back({{"id", x.id},
                    {"parameter", x.parameter},
                    {"unit", x.unit},
                    {"smallest_change", x.smallest_change}});
  return list;
}

}  // namespace

Json parameters_json(const Parameters& parameters) {
  Json j = Json::object();
  for (const auto& p : parameters)
    if (p.is_count)
      j[p.name] = static_cast<std::size_t>(p.value);
    else
      j[p.name] = p.value;
  return j;
}

Json analysis_json(const AnalysisResult& r) {
  const Findings& f = r.findings;
  Json J;
  J["headline"] = r.headline;
  J["system"] = f.system;
  J["recording"] = f.recording;
  J["samples"] = f.samples;
  J["samples_used"] = f.samples_used;
  Json method{{"domain", f.method.domain},         {"filter", f.method.filter},
              {"decimation", f.method.decimation}, {"folds", f.method.folds},
              {"selection", f.method.selection},   {"moving_only", f.method.moving_only}};
  put(method, "identification_bandwidth_hz", f.method.identification_bandwidth_hz);
  J["method"] = method;
  J["noise_floor_n"] = f.noise_floor_n;
  // Present when the noise is below a logging step; no step found (a constant column) is none.
  if (f.noise_step_n && *f.noise_step_n > 0) J["noise_step_n"] = *f.noise_step_n;
  // No sample used: no fit, and no error figure (null), not a perfect one (0).
  J["baseline"] = f.samples_used > 0 ? errors_json(f.baseline) : Json(nullptr);
  J["final"] = f.samples_used > 0 ? errors_json(f.final_fit) : Json(nullptr);
  J["effects"] = Json::array();
  for (const auto& e : f.effects) J["effects"].push_back(effect_json(e));
  put(J, "nothing_missing", f.nothing_missing);
  J["conclusion"] = f.conclusion;
  J["not_selected"] = Json::array();
  for (const auto& n : f.not_selected) {
    Json j{{"id", n.id}, {"heldout_gain_pct", n.heldout_gain_pct}, {"t_stat", n.t_stat}};
    put(j, "worst_segment_pct", n.worst_segment_pct);
    put(j, "explained_rms_n", n.explained_rms_n);
    put(j, "reason", n.reason);
    if (n.parameters) j["parameters"] = parameters_json(*n.parameters);
    J["not_selected"].push_back(j);
  }
  J["validation"] = Json::array();
  for (const auto& v : f.validation) {
    Json j{{"model", v.model},
           {"heldout_rms", v.heldout_rms_n},
           {"heldout_relative_error_pct", v.heldout_relative_error_pct}};
    put(j, "fitted_rms", v.fitted_rms_n);
    put(j, "fitted_relative_error_pct", v.fitted_relative_error_pct);
    J["validation"].push_back(j);
  }
  J["events"] = Json::array();
  for (const auto& e : f.events) J["events"].push_back(event_json(e));
  if (f.breakaway_test) {
    const auto side = [](const BreakawaySide& s) {
      return Json{
          {"episodes", s.episodes}, {"median_excess_n", s.median_excess_n}, {"se_n", s.se_n}};
    };
    J["breakaway_test"] = {{"pos", side(f.breakaway_test->pos)},
                           {"neg", side(f.breakaway_test->neg)}};
  }
  J["where"] = r.where;
  put(J, "reversals", f.reversals);
  put(J, "input_edges", f.input_edges);
  if (f.twin_simulation) J["twin_simulation"] = twin_json(*f.twin_simulation);
  if (f.unexplained) {
    const auto& u = *f.unexplained;
    J["unexplained"] = {{"message", u.message},
                        {"closest_id", u.id},
                        {"parameters", parameters_json(u.parameters)},
                        {"heldout_gain_pct", u.heldout_gain_pct},
                        {"explained_rms_n", u.explained_rms_n},
                        {"where", u.where},
                        {"check", u.check}};
  }
  if (f.twin_force_check) {
    const auto& c = *f.twin_force_check;
    J["twin_force_check"] = c.available ? Json{{"available", true},
                                               {"baseline_mae_n", c.baseline_mae_n},
                                               {"corrected_mae_n", c.corrected_mae_n},
                                               {"resolved_n", c.resolved_n},
                                               {"kept", c.kept},
                                               {"dropped", c.dropped}}
                                        : Json{{"available", false}, {"reason", c.reason}};
  }
  if (!f.sliding_note.empty()) J["sliding_note"] = f.sliding_note;
  if (!f.resolvable.empty()) J["resolvable"] = resolvable_json(f.resolvable);
  return J;
}

}  // namespace maglead::report
