// The analysis's part of a report page (see analysis_part.hpp).
#include "analysis_part.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <vector>

#include "effect_text.hpp"
#include "maglead/effects/axis_kind.hpp"
#include "maglead/report/html.hpp"
#include "maglead/report/plot.hpp"
#include "maglead/report/time_chart.hpp"

namespace maglead::report {
namespace {

constexpr const char* kStyle = R"css(
body{font-family:system-ui,sans-serif;max-width:1150px;margin:0 auto;padding:0 12px 2em;
  color:#222;line-height:1.4}
h1{font-size:1.45em;margin:.6em 0 .3em}
h2{font-size:1.2em;border-bottom:1px solid #ccc;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0;display:block;overflow-x:auto;max-width:100%;
background:linear-gradient(to right,#fff 30%,rgba(255,255,255,0)),
linear-gradient(to right,rgba(255,255,255,0),#fff 70%) 100% 0,
radial-gradient(farthest-side at 0 50%,rgba(0,0,0,.25),rgba(0,0,0,0)),
radial-gradient(farthest-side at 100% 50%,rgba(0,0,0,.25),rgba(0,0,0,0)) 100% 0;
background-repeat:no-repeat;background-size:40px 100%,40px 100%,14px 100%,14px 100%;
background-attachment:local,local,scroll,scroll}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;vertical-align:top}
.ok{background:#e6f4e6;padding:.6em}.bad{background:#fbe9e7;padding:.6em}.unjudged{background:#fff4d6;padding:.6em}
figure{margin:1em 0;border:1px solid #ddd;padding:8px;box-sizing:border-box;max-width:100%}
figcaption{color:#444;font-size:.92em;margin-bottom:4px}
.legend{font-size:.85em;min-height:1.3em;margin:2px 0 4px}
.plot{width:100%;height:260px}.map{max-width:100%;height:auto;display:block}
.hint,.meaning{color:#666;font-size:.9em}code{font-size:.95em}
)css";

using Status = AnalysisOutcome::Status;

std::string quantity(const effects::AxisKind& k) { return std::string(k.quantity); }
std::string unit(const effects::AxisKind& k) { return std::string(k.drive_unit); }

// One line per parameter, by name (as analysis.json has them), with its standard error if any.
std::string parameters_html(const effects::AxisKind& kind, const std::string& id,
                            const analysis::Parameters& params,
                            const analysis::Parameters& errors = {},
                            const analysis::Parameters& calibration_errors = {}) {
  std::vector<const analysis::Parameter*> sorted;
  for (const auto& p : params) sorted.push_back(&p);
  std::sort(sorted.begin(), sorted.end(), [](auto* a, auto* b) { return a->name < b->name; });
  std::string h;
  for (const auto* p : sorted) {
    const double se = analysis::parameter_value(errors, p->name, 0.0);
    h += (h.empty() ? "" : "<br>") + parameter_html(id, p->name, p->value, se, kind);
    // Beside fitted values, one without an error was scanned on a grid or held at the model's.
    if (!errors.empty() && analysis::value_with_error(p->value, se).empty())
      h += " <span class=\"meaning\">(no standard error: scanned on a grid or held at the model's "
           "value)</span>";
    if (const double c = analysis::parameter_value(calibration_errors, p->name, 0.0); c > 0)
      h += " (calibration ± " + analysis::calibration_bound_text(p->name, c) + ")";
  }
  return h;
}

std::string evidence_text(const analysis::EffectFinding& e) {
  const auto& ev = e.evidence;
  if (!ev.heldout_gain_pct) return "";
  // As analyze prints them: 99.95 %, never rounded up to 100 %.
  std::string s = "held-out gain " + fixed(*ev.heldout_gain_pct, 2) + " %";
  if (ev.t_stat) s += ", t = " + fixed(*ev.t_stat, 1);
  if (ev.segments_improved) s += ", " + *ev.segments_improved + " segments better";
  return s;
}

// The force (torque) a finding changes beside what it had to exceed, as `analyze` prints it.
std::string floors_text(const analysis::Evidence& ev, const effects::AxisKind& kind) {
  if (!ev.explained_rms_n) return "";
  const std::string u = " " + unit(kind);
  std::string s =
      "changes the " + quantity(kind) + " by " + number(*ev.explained_rms_n, 4) + u + " RMS";
  if (ev.resolution_floor_n) s += "; the recording resolves " + number(*ev.resolution_floor_n) + u;
  if (ev.minimum_n) s += ", the stated minimum " + number(*ev.minimum_n) + u;
  return s;
}

// `axis`: the axis the findings are of, nullptr on the actuator.
std::string effect_row(const analysis::EffectFinding& e, const effects::AxisKind& kind,
                       const effects::AxisKind* axis) {
  std::string h =
      "<tr><td><b>" + escape_html(effect_title(e.id)) + "</b><br><code>" + escape_html(e.id) +
      "</code></td><td>" + escape_html(effect_law(e.id, axis)) + "</td><td>" +
      parameters_html(kind, e.id, e.parameters, e.standard_errors, e.calibration_errors) +
      "</td><td>" + escape_html(e.where);
  if (!e.finding.empty()) h += "<br>" + escape_html(e.finding);
  if (const auto ev = evidence_text(e); !ev.empty()) h += "<br>" + escape_html(ev);
  if (const auto f = floors_text(e.evidence, kind); !f.empty()) h += "<br>" + escape_html(f);
  for (const auto& alt : e.alternatives)
    h += "<br>alternative: <b>" + escape_html(effect_title(alt.id)) + "</b> " +
         parameters_html(kind, alt.id, alt.parameters) + " (reproduces " +
         number(alt.explains_pct) + " %)";
  return h + "</td></tr>\n";
}

// Where the baseline misfits, in words (the axis path locates it over velocity, position, time).
std::string where_list(const analysis::AnalysisResult& r) {
  if (r.where.empty()) return "";
  std::string h = "<p>Where the model as configured misfits:</p>\n<ul>";
  for (const auto& w : r.where) h += "<li>" + escape_html(w) + "</li>";
  return h + "</ul>\n";
}

// The missing force (torque) over time, on the same time axis as the page's other plots.
std::string fit_chart(const analysis::AnalysisResult& r) {
  const auto& fit = r.fit_over_time;
  if (fit.curves.empty() || fit.curves.front().x.size() < 2) return "";
  TimeChart c;
  c.id = "fit";
  c.title = fit.title;
  c.caption = "The " + quantity(axis_words(r.findings)) +
              " the model leaves out at the samples the analysis fits, before and after the "
              "effects it found.";
  c.y_label = fit.y_label;
  c.t_s = &fit.curves.front().x;
  for (const auto& curve : fit.curves) c.series.push_back({curve.label, curve.y});
  return time_chart_html(c);
}

std::string heldout_cell(const std::optional<double>& rms) {
  return "<td>" + (rms ? number(*rms, 4) : std::string("–")) + "</td>";
}

std::string fit_table(const analysis::Findings& F) {
  // Four figures, as analyze prints them (17.99 %, not 18, beside 2.551 %).
  const auto rel = [](const analysis::FitErrors& e) { return number(e.relative_error_pct, 4); };
  const auto rms = [](const analysis::FitErrors& e) { return number(e.rms_n, 4); };
  std::optional<double> ho_before, ho_after;
  if (!F.validation.empty()) {
    ho_before = F.validation.front().heldout_rms_n;
    ho_after = F.validation.back().heldout_rms_n;
  }
  const std::string u = unit(axis_words(F)), q = quantity(axis_words(F));
  if (F.samples_used == 0)
    return "<p>No fit: no sample was used (" + escape_html(F.sliding_note) + ").</p>\n";
  if (F.effects.empty())
    return "<p>One fit, since nothing was added: the model's " + q + " error is " +
           rms(F.baseline) + " " + u + " RMS (" + rel(F.baseline) + " % of the " + q + ").</p>\n";
  return "<table><tr><th>model</th><th>" + q + " error RMS [" + u +
         "]</th><th>relative error [%]</th><th>held-out RMS [" + u +
         "]</th></tr>\n<tr><td>before (the model as configured)</td><td>" + rms(F.baseline) +
         "</td><td>" + rel(F.baseline) + "</td>" + heldout_cell(ho_before) +
         "</tr>\n<tr><td>after (with the effects above)</td><td>" + rms(F.final_fit) + "</td><td>" +
         rel(F.final_fit) + "</td>" + heldout_cell(ho_after) + "</tr></table>\n";
}

// A missing force no library effect explains plausibly: what would, where, what to check.
std::string unexplained_box(const analysis::Findings& F) {
  if (!F.unexplained) return "";
  const auto& u = *F.unexplained;
  return "<p class=\"bad\" id=\"unexplained\">" + escape_html(u.message) +
         "<br>where: " + escape_html(u.where) + "<br>check: " + escape_html(u.check) + "</p>\n";
}

// The candidates the selection weighed and left out, each with why (the best one below the
// threshold, those the backward check dropped, those refused in the final fit).
std::string left_out_table(const analysis::Findings& F) {
  if (F.not_selected.empty()) return "";
  const effects::AxisKind& kind = axis_words(F);
  std::string h =
      "<p>Considered and left out:</p>\n<table id=\"left-out\"><tr><th>effect</th><th>why</th>"
      "<th>held-out gain [%]</th><th>t</th><th>" +
      quantity(kind) + " it would explain [" + unit(kind) + " RMS]</th><th>parameters</th></tr>\n";
  for (const auto& r : F.not_selected)
    h += "<tr><td>" + escape_html(effect_title(r.id)) + "<br><code>" + escape_html(r.id) +
         "</code></td><td>" + escape_html(r.reason.value_or("")) + "</td><td>" +
         fixed(r.heldout_gain_pct, 2) + "</td><td>" + fixed(r.t_stat, 2) + "</td><td>" +
         (r.explained_rms_n ? fixed(*r.explained_rms_n, 3) : std::string("–")) + "</td><td>" +
         (r.parameters ? parameters_html(kind, r.id, *r.parameters) : std::string("–")) +
         "</td></tr>\n";
  return h + "</table>\n";
}

// The twin's own force estimate with the model as configured and as corrected (checking only:
// the live observer never reads the load cell).
std::string twin_force_text(const analysis::Findings& F) {
  if (!F.twin_force_check) return "";
  const auto& c = *F.twin_force_check;
  if (!c.available)
    return "<p id=\"twin-force\">The twin's force estimate was not checked (" +
           escape_html(c.reason) + ").</p>\n";
  std::string h =
      "<p id=\"twin-force\">The twin's force estimate against the load cell "
      "(checking only): mean absolute error " +
      number(c.baseline_mae_n) + " N with the model as configured, " + number(c.corrected_mae_n) +
      " N with the corrected model.";
  for (const auto& d : c.dropped)
    h += " " + escape_html(d) + " is left out of the corrected model: it raised that error.";
  return h + "</p>\n";
}

plot::Panel panel_of(const analysis::Chart& c) {
  plot::Panel p{c.title, c.x_label, c.y_label, {}};
  for (const auto& curve : c.curves) p.series.push_back({curve.label, curve.x, curve.y});
  return p;
}

plot::HeatMap heatmap_of(const analysis::Grid& g) {
  return {g.title, g.x_label, g.y_label, g.value_label, g.x_min, g.x_max,
          g.y_min, g.y_max,   g.nx,      g.ny,          g.values};
}

}  // namespace

const effects::AxisKind& axis_words(const analysis::Findings& F) {
  const effects::AxisKind* k = effects::axis_kind_of_system(F.system);
  return k ? *k : effects::linear_axis();
}

std::string page_head(const std::string& title) {
  return "<meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, "
         "initial-scale=1\">\n<title>" +
         escape_html(title) + "</title>\n<style>" + kStyle + "</style>\n" + time_chart_head();
}

namespace {
/// The laws the selection could not judge on this recording (their reason says "not judged: …").
std::string unjudged_laws(const analysis::Findings& F) {
  std::string s;
  for (const auto& r : F.not_selected)
    if (r.reason && r.reason->starts_with(analysis::kNotJudged))
      s += (s.empty() ? "" : ", ") + r.id;
  return s;
}
}  // namespace

const char* conclusion_class(const analysis::Findings& F) {
  if (F.conclusion.starts_with("not judged")) return "unjudged";
  // The actuator leaves nothing_missing unset: its conclusion says it (selection::conclusion_of).
  const bool judged_nothing = F.conclusion.starts_with("nothing is missing") &&
                              F.nothing_missing.value_or(true) && F.effects.empty() &&
                              !F.unexplained;
  // Nothing missing among the laws judged is no all-clear while some were not judged.
  if (judged_nothing) return unjudged_laws(F).empty() ? "ok" : "unjudged";
  return "bad";
}

std::string physics_section(const AnalysisOutcome& o, int number) {
  std::string h =
      "<h2 id=\"physics\">" + std::to_string(number) + ". What physics is missing</h2>\n";
  if (o.status == Status::skipped)
    return h + "<p>The analysis was not run (" + escape_html(o.reason) + ").</p>\n";
  if (o.status == Status::failed)
    return h + "<p>The analysis could not run on this recording: " + escape_html(o.reason) +
           "</p>\n";
  const auto& F = o.result->findings;
  const effects::AxisKind& kind = axis_words(F);
  const std::string note =
      F.sliding_note.empty()
          ? ""
          : "<p class=\"meaning\">Note: " + escape_html(F.sliding_note) + "</p>\n";
  // What follows the findings on every page: the unexplained force, the note, the left-out.
  const std::string after = unexplained_box(F) + note + left_out_table(F) + where_list(*o.result);
  if (F.effects.empty() && F.unexplained) return h + after;
  if (F.effects.empty() && F.conclusion.rfind("not judged", 0) == 0)
    return h + "<p class=\"unjudged\">" + escape_html(F.conclusion) +
           escape_html(kind.words(": the model is not judged, and stays as it is; a recording "
                                  "where the nut slides (moves, force steps) can judge it.")) +
           "</p>\n" + after;
  const std::string cls = conclusion_class(F);
  // No effect named beside a misfit is no all-clear: the box says so in the headline's colour.
  if (F.effects.empty())
    return h + "<p class=\"" + cls +
           "\">Nothing: the analysis adds no effect. None from the library explains a "
           "significant part of the held-out " +
           quantity(kind) + " error, so the model stays as it is" +
           (cls == std::string("ok") ? ""
            : cls == std::string("unjudged")
                ? "; but not every law was judged on this recording: " + unjudged_laws(F) +
                      " (see the laws left out)"
                : "; but it does not explain the recording: " + escape_html(F.conclusion)) +
           ".</p>\n" + after;
  h += "<p>The analysis compared the model with the recording in the " + quantity(kind) +
       " domain and names what it lacks (effects, laws and parameter names of "
       "docs/effects.md):</p>\n<table><tr><th>effect</th><th>law</th><th>parameters</th>"
       "<th>where, evidence</th></tr>\n";
  const effects::AxisKind* axis = effects::axis_kind_of_system(F.system);
  for (const auto& e : F.effects) h += effect_row(e, kind, axis);
  return h + "</table>\n" + after;
}

std::string fit_part(const AnalysisOutcome& o) {
  if (o.status != Status::done) return "";
  const auto& fitted = o.result->findings.final_fit;
  std::string totals;
  if (!fitted.summary.empty())
    totals = "<p>The model's own values as fitted: " +
             parameters_html(axis_words(o.result->findings), "",
                             fitted.fitted_parameters.value_or(analysis::Parameters{}),
                             fitted.standard_errors) +
             "</p>\n";
  return fit_table(o.result->findings) + totals + fit_chart(*o.result) +
         twin_force_text(o.result->findings);
}

std::string analysis_events(const AnalysisOutcome& o) {
  if (o.status != Status::done) return "";
  std::string h;
  for (const auto& e : o.result->findings.events) {
    if (e.type != "external_disturbance") continue;
    h += "<tr><td>" + number(e.t_s, 6) + "</td><td>" + number(e.duration_s.value_or(NAN)) +
         "</td><td>" + number(e.force_n.value_or(NAN)) + "</td></tr>\n";
  }
  if (h.empty()) return "";
  const effects::AxisKind& kind = axis_words(o.result->findings);
  return "<table><tr><th>" + quantity(kind) + " pulse at [s]</th><th>lasting [s]</th><th>" +
         quantity(kind) + " [" + unit(kind) + "]</th></tr>\n" + h + "</table>\n";
}

std::string analysis_figures(const AnalysisOutcome& o) {
  if (o.status != Status::done) return "";
  std::string h;
  for (const auto& f : o.result->figures) {
    std::string png;
    if (f.is_grid) {
      png = plot::heatmap_png(heatmap_of(f.grid));
    } else {
      std::vector<plot::Panel> panels;
      for (const auto& c : f.charts) panels.push_back(panel_of(c));
      png = plot::panels_png(panels, 1100, 300);
    }
    h += "<figure><figcaption>" + escape_html(f.caption) +
         "</figcaption>\n<img class=\"map\" alt=\"" + escape_html(f.caption) + "\" src=\"" +
         data_url_of_png_bytes(png) + "\"></figure>\n";
  }
  return h;
}

}  // namespace maglead::report
