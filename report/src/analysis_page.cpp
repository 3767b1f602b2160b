// analysis.json for machines, report.html (figures embedded as base64) for people.
#include "maglead/report/analysis_page.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

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

std::string params_text(const nlohmann::json& p) {
  std::string s;
  for (auto it = p.begin(); it != p.end(); ++it) {
    if (!s.empty()) s += ", ";
    s += it.key() + " = " +
         (it.value().is_number() ? num(it.value().get<double>()) : it.value().dump());
  }
  return s;
}

// "step_out at t = 3.2 s: leads 1, start_s 3.1": an event in words, not as JSON.
std::string event_text(const nlohmann::json& e) {
  std::string s = e.value("type", "event") + " at t = " + number(e.value("t_s", NAN), 5) + " s";
  std::string rest;
  for (auto it = e.begin(); it != e.end(); ++it)
    if (it.key() != "type" && it.key() != "t_s" && it.value().is_number())
      rest += (rest.empty() ? "" : ", ") + it.key() + " " + number(it.value().get<double>(), 4);
  return rest.empty() ? s : s + ": " + rest;
}

std::string twin_simulation_text(const nlohmann::json& t) {
  if (!t.value("available", false))
    return "not run (" + t.value("reason", std::string("no reason given")) + ")";
  return "position error RMS " + number(t.value("baseline_rms_position_error_m", NAN) * 1e6) +
         " µm with the baseline, " + number(t.value("corrected_rms_position_error_m", NAN) * 1e6) +
         " µm corrected, over " + std::to_string(t.value("windows", 0)) + " windows of " +
         number(t.value("horizon_s", NAN)) + " s";
}

}  // namespace

void write_analysis_outputs(const AnalysisResult& r, const std::string& out_dir) {
  namespace fs = std::filesystem;
  fs::create_directories(out_dir);
  const auto path = [&](const std::string& f) { return (fs::path(out_dir) / f).string(); };
  const nlohmann::json J = analysis_json(r);
  {
    std::ofstream j(path("analysis.json"));
    j << J.dump(2) << "\n";
    if (!j) throw std::runtime_error("cannot write " + path("analysis.json"));
  }
  analysis::save_model(
      path("model_corrected.toml"), r.corrected,
      "model corrected by maglead analyze from " + r.findings.recording);
  // The fit over time is a chart of its own in the result; here it is one more figure.
  std::vector<analysis::Figure> figures = r.figures;
  if (!r.fit_over_time.curves.empty())
    figures.push_back({"fit_time.png", "The force the model leaves out at sliding samples",
                       {r.fit_over_time}, false, {}});
  for (const auto& f : figures) {
    if (f.is_grid) {
      plot::save_heatmap_png(path(f.file), heatmap_of(f.grid));
    } else {
      std::vector<plot::Panel> panels;
      for (const auto& c : f.charts) panels.push_back(panel_of(c));
      plot::save_panels_png(path(f.file), panels, 1100, 300);
    }
  }
  std::ostringstream h;
  h << "<!doctype html><html><head><meta charset=\"utf-8\"><title>maglead analyze</title><style>"
       "body{font-family:sans-serif;max-width:1150px;margin:auto}table{border-collapse:collapse}"
       "td,th{border:1px solid #aaa;padding:3px 8px}img{max-width:100%}.alt{color:#a40}</style>"
       "</head><body>\n";
  h << "<h1>Twin versus recording</h1><p>Recording <code>"
    << escape_html(J["recording"].get<std::string>()) << "</code> (" << J["samples"] << " samples, "
    << J["samples_used"] << " used), system <b>" << escape_html(J["system"].get<std::string>())
    << "</b>.</p>\n";
  h << "<p>Method: " << escape_html(J["method"]["domain"].get<std::string>()) << "; "
    << escape_html(J["method"]["filter"].get<std::string>()) << "; decimation "
    << J["method"]["decimation"] << "; " << escape_html(J["method"]["selection"].get<std::string>())
    << "; " << escape_html(J["method"]["moving_only"].get<std::string>())
    << ". Noise floor of the force: " << num(J["noise_floor_n"].get<double>()) << " N.</p>\n";
  h << "<h2>1. Compare</h2><table><tr><th></th><th>RMS [N]</th><th>relative error [%]</th>"
       "<th>full rate RMS [N]</th><th>full rate relative error [%]</th></tr>";
  for (const char* k : {"baseline", "final"}) {
    const auto& e = J[k];
    h << "<tr><td>" << k << "</td><td>" << num(e["rms"].get<double>()) << "</td><td>"
      << num(e["relative_error_pct"].get<double>()) << "</td><td>"
      << num(e["full_rate"]["rms"].get<double>()) << "</td><td>"
      << num(e["full_rate"]["relative_error_pct"].get<double>()) << "</td></tr>";
  }
  h << "</table>\n";
  h << "<h2>2. Locate</h2><ul>";
  for (const auto& w : r.where) h << "<li>" << escape_html(w) << "</li>";
  if (r.where.empty()) h << "<li>no region stands out</li>";
  h << "</ul><p>Events:</p><ul>";
  for (const auto& e : J["events"]) h << "<li>" << escape_html(event_text(e)) << "</li>";
  if (J["events"].empty()) h << "<li>none</li>";
  h << "</ul>\n<h2>3. Explain</h2><p><b>" << escape_html(J["conclusion"].get<std::string>())
    << "</b></p>";
  h << "<table><tr><th>#</th><th>effect</th><th>parameters</th><th>where</th><th>held-out gain</th>"
       "<th>t</th><th>segments</th><th>improvement</th></tr>";
  int k = 1;
  for (const auto& e : J["effects"]) {
    const auto& ev = e["evidence"];
    h << "<tr><td>" << k++ << "</td><td><b>" << escape_html(e["id"].get<std::string>()) << "</b>";
    if (e.contains("finding"))
      h << "<div class=alt>" << escape_html(e["finding"].get<std::string>()) << "</div>";
    if (e.contains("alternatives"))
      for (const auto& a : e["alternatives"])
        h << "<div class=alt>alternative: " << escape_html(a["id"].get<std::string>()) << " ("
          << escape_html(params_text(a["parameters"])) << "; reproduces "
          << num(a["explains_pct"].get<double>(), 3) << " %)</div>";
    if (e.contains("note")) h << "<div>" << escape_html(e["note"].get<std::string>()) << "</div>";
    h << "</td><td>" << escape_html(params_text(e["parameters"])) << "</td><td>"
      << escape_html(e["where"].get<std::string>()) << "</td><td>"
      << (ev["heldout_gain_pct"].is_number() ? num(ev["heldout_gain_pct"].get<double>(), 3) + " %"
                                             : "–")
      << "</td><td>" << (ev.contains("t_stat") ? num(ev["t_stat"].get<double>(), 3) : "–")
      << "</td><td>"
      << (ev.contains("segments_improved") ? ev["segments_improved"].get<std::string>() : "–")
      << "</td><td>" << num(e["improvement_pct"].get<double>(), 3) << " %</td></tr>";
  }
  h << "</table>";
  for (const auto& rj : J["not_selected"])
    h << "<p>Next best candidate, not significant: " << escape_html(rj["id"].get<std::string>())
      << " (held-out gain " << num(rj["heldout_gain_pct"].get<double>(), 3)
      << " %, t = " << num(rj["t_stat"].get<double>(), 3) << ")</p>";
  h << "<h2>4. Model it</h2><table><tr><th>model</th><th>held-out RMS [N]</th><th>held-out "
       "relative error [%]</th></tr>";
  for (const auto& v : J["validation"])
    h << "<tr><td>" << escape_html(v["model"].get<std::string>()) << "</td><td>"
      << num(v["heldout_rms"].get<double>()) << "</td><td>"
      << num(v["heldout_relative_error_pct"].get<double>()) << "</td></tr>";
  h << "</table><p>Corrected model written to <code>model_corrected.toml</code>.</p>";
  if (J.contains("twin_simulation"))
    h << "<p>Twin re-simulation from measured states: "
      << escape_html(twin_simulation_text(J["twin_simulation"])) << "</p>";
  h << "<h2>Figures</h2>";
  for (const auto& f : figures)
    h << "<figure><img src=\"" << png_data_url(path(f.file)) << "\" alt=\"" << escape_html(f.file)
      << "\"><figcaption>" << escape_html(f.caption) << "</figcaption></figure>\n";
  h << "</body></html>\n";
  std::ofstream out(path("report.html"));
  out << h.str();
  if (!out) throw std::runtime_error("cannot write " + path("report.html"));
}

}  // namespace maglead::report
