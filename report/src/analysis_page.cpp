// analysis.json for machines, report.html (figures embedded as base64) for people.
#include "maglead/report/analysis_page.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "maglead/fileio/atomic_file.hpp"
#include "maglead/report/analysis_json.hpp"
#include "maglead/report/html.hpp"
#include "maglead/report/plot.hpp"

namespace maglead::report {
namespace {

using analysis::AnalysisResult;

plot::Panel panel_of(const analysis::Chart& c) {
  plot::Panel p{c.title, c.x_label, c.y_label, {}};
  for (const auto& curve : c.curves) p.series.push_back({curve.label, curve.x, curve.y});
  return p;
}

plot::HeatMap heatmap_of(const analysis::Grid& g) {
  return {g.title, g.x_label, g.y_label, g.value_label, g.x_min, g.x_max,
          g.y_min, g.y_max,   g.nx,      g.ny,          g.values};
}

std::string num(double v, int prec = 4) {
  std::ostringstream o;
  o.precision(prec);
  o << v;
  return o.str();
}

// "a = 1, b = 2", by name (as analysis.json has them).
std::string params_text(const analysis::Parameters& p) {
  std::vector<const analysis::Parameter*> sorted;
  for (const auto& q : p) sorted.push_back(&q);
  std::sort(sorted.begin(), sorted.end(), [](auto* a, auto* b) { return a->name < b->name; });
  std::string s;
  for (const auto* q : sorted) s += (s.empty() ? "" : ", ") + q->name + " = " + num(q->value);
  return s;
}

// "step_out at t = 3.2 s: leads 1, start_s 3.1": an event in words, not as JSON.
std::string event_text(const analysis::Event& e) {
  std::string s = e.type + " at t = " + number(e.t_s, 5) + " s";
  std::string rest;
  const auto add = [&](const char* name, std::optional<double> v) {
    if (v) rest += (rest.empty() ? "" : ", ") + std::string(name) + " " + number(*v, 4);
  };
  add("duration_s", e.duration_s);
  add("force_n", e.force_n);
  add("leads", e.leads ? std::optional<double>(*e.leads) : std::nullopt);
  add("residual_n", e.residual_n);
  add("rms_n", e.rms_n);
  add("start_s", e.start_s);
  return rest.empty() ? s : s + ": " + rest;
}

std::string twin_simulation_text(const analysis::TwinSimulation& t) {
  if (!t.available) return "not run (" + t.reason + ")";
  return "position error RMS " + number(t.baseline_rms_position_error_m * 1e6) +
         " µm with the baseline, " + number(t.corrected_rms_position_error_m * 1e6) +
         " µm corrected, over " + std::to_string(t.windows) + " windows of " + number(t.horizon_s) +
         " s";
}

}  // namespace

void write_analysis_outputs(const AnalysisResult& r, const std::string& out_dir) {
  namespace fs = std::filesystem;
  fs::create_directories(out_dir);
  const auto path = [&](const std::string& f) { return (fs::path(out_dir) / f).string(); };
  write_file_atomically(path("analysis.json"), analysis_json(r).dump(2) + "\n");
  analysis::save_model(path("model_corrected.toml"), r.corrected,
                       "model corrected by maglead analyze from " + r.findings.recording);
  // The fit over time is a chart of its own in the result; here it is one more figure.
  std::vector<analysis::Figure> figures = r.figures;
  if (!r.fit_over_time.curves.empty())
    figures.push_back({"fit_time.png",
                       "The force the model leaves out at sliding samples",
                       {r.fit_over_time},
                       false,
                       {}});
  for (const auto& f : figures) {
    if (f.is_grid) {
      plot::save_heatmap_png(path(f.file), heatmap_of(f.grid));
    } else {
      std::vector<plot::Panel> panels;
      for (const auto& c : f.charts) panels.push_back(panel_of(c));
      plot::save_panels_png(path(f.file), panels, 1100, 300);
    }
  }
  const analysis::Findings& F = r.findings;
  std::ostringstream h;
  h << "<!doctype html><html><head><meta charset=\"utf-8\"><title>maglead analyze</title><style>"
       "body{font-family:sans-serif;max-width:1150px;margin:auto}table{border-collapse:collapse}"
       "td,th{border:1px solid #aaa;padding:3px 8px}img{max-width:100%}.alt{color:#a40}</style>"
       "</head><body>\n";
  h << "<h1>Twin versus recording</h1><p>Recording <code>" << escape_html(F.recording)
    << "</code> (" << F.samples << " samples, " << F.samples_used << " used), system <b>"
    << escape_html(F.system) << "</b>.</p>\n";
  h << "<p>Method: " << escape_html(F.method.domain) << "; " << escape_html(F.method.filter)
    << "; decimation " << F.method.decimation << "; " << escape_html(F.method.selection) << "; "
    << escape_html(F.method.moving_only) << ". Noise floor of the force: " << num(F.noise_floor_n)
    << " N.</p>\n";
  h << "<h2>1. Compare</h2><table><tr><th></th><th>RMS [N]</th><th>relative error [%]</th>"
       "<th>full rate RMS [N]</th><th>full rate relative error [%]</th></tr>";
  for (const auto& [k, e] : {std::pair{"baseline", &F.baseline}, std::pair{"final", &F.final_fit}})
    h << "<tr><td>" << k << "</td><td>" << num(e->rms_n) << "</td><td>"
      << num(e->relative_error_pct) << "</td><td>" << num(e->full_rate_rms_n) << "</td><td>"
      << num(e->full_rate_relative_error_pct) << "</td></tr>";
  h << "</table>\n";
  h << "<h2>2. Locate</h2><ul>";
  for (const auto& w : r.where) h << "<li>" << escape_html(w) << "</li>";
  if (r.where.empty()) h << "<li>no region stands out</li>";
  h << "</ul><p>Events:</p><ul>";
  for (const auto& e : F.events) h << "<li>" << escape_html(event_text(e)) << "</li>";
  if (F.events.empty()) h << "<li>none</li>";
  h << "</ul>\n<h2>3. Explain</h2><p><b>" << escape_html(F.conclusion) << "</b></p>";
  h << "<table><tr><th>#</th><th>effect</th><th>parameters</th><th>where</th><th>held-out gain</th>"
       "<th>t</th><th>segments</th><th>improvement</th></tr>";
  int k = 1;
  for (const auto& e : F.effects) {
    const auto& ev = e.evidence;
    h << "<tr><td>" << k++ << "</td><td><b>" << escape_html(e.id) << "</b>";
    if (!e.finding.empty()) h << "<div class=alt>" << escape_html(e.finding) << "</div>";
    for (const auto& a : e.alternatives)
      h << "<div class=alt>alternative: " << escape_html(a.id) << " ("
        << escape_html(params_text(a.parameters)) << "; reproduces " << num(a.explains_pct, 3)
        << " %)</div>";
    if (!e.note.empty()) h << "<div>" << escape_html(e.note) << "</div>";
    h << "</td><td>" << escape_html(params_text(e.parameters)) << "</td><td>"
      << escape_html(e.where) << "</td><td>"
      << (ev.heldout_gain_pct ? num(*ev.heldout_gain_pct, 3) + " %" : "–") << "</td><td>"
      << (ev.t_stat ? num(*ev.t_stat, 3) : "–") << "</td><td>" << ev.segments_improved.value_or("–")
      << "</td><td>" << num(e.improvement_pct, 3) << " %</td></tr>";
  }
  h << "</table>";
  for (const auto& n : F.not_selected)
    h << "<p>Next best candidate, not significant: " << escape_html(n.id) << " (held-out gain "
      << num(n.heldout_gain_pct, 3) << " %, t = " << num(n.t_stat, 3) << ")</p>";
  h << "<h2>4. Model it</h2><table><tr><th>model</th><th>held-out RMS [N]</th><th>held-out "
       "relative error [%]</th></tr>";
  for (const auto& v : F.validation)
    h << "<tr><td>" << escape_html(v.model) << "</td><td>" << num(v.heldout_rms_n) << "</td><td>"
      << num(v.heldout_relative_error_pct) << "</td></tr>";
  h << "</table><p>Corrected model written to <code>model_corrected.toml</code>.</p>";
  if (F.twin_simulation)
    h << "<p>Twin re-simulation from measured states: "
      << escape_html(twin_simulation_text(*F.twin_simulation)) << "</p>";
  h << "<h2>Figures</h2>";
  for (const auto& f : figures)
    h << "<figure><img src=\"" << png_data_url(path(f.file)) << "\" alt=\"" << escape_html(f.file)
      << "\"><figcaption>" << escape_html(f.caption) << "</figcaption></figure>\n";
  h << "</body></html>\n";
  write_file_atomically(path("report.html"), h.str());
}

}  // namespace maglead::report
