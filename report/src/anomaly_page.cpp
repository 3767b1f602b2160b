// The anomaly report page (see anomaly_page.hpp). Sections in the order a reader asks: where the
// twin and the machine part, what physics is missing, the fit before and after, the events.
#include "maglead/report/anomaly_page.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "analysis_part.hpp"
#include "effect_text.hpp"
#include "maglead/fileio/atomic_file.hpp"
#include "maglead/report/analysis_json.hpp"
#include "maglead/report/html.hpp"
#include "maglead/report/plot.hpp"
#include "maglead/report/time_chart.hpp"

namespace maglead::report {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;
using analysis::Anomaly;

// The static estimate is judged off only beyond this mean error against the load cell (2.25 N
// on hand-push, docs/simulation.md) and beyond the model's friction, which it cannot see.
constexpr double kStaticAttention_n = 3.0;

std::string seconds(double t_s) { return number(t_s, 6); }

bool any_finite(const std::vector<double>& v) {
  return std::any_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

// ---------------------------------------------------------------- section 1: where they part
std::vector<double> scaled(const std::vector<double>& v, double factor) {
  std::vector<double> out(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) out[i] = v[i] * factor;
  return out;
}

std::vector<double> difference(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> out(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) out[i] = a[i] - b[i];
  return out;
}

TimeChart chart_of(const Anomaly& a, std::string id, std::string title, std::string caption,
                   std::string y_label) {
  TimeChart c;
  c.id = std::move(id);
  c.title = std::move(title);
  c.caption = std::move(caption);
  c.y_label = std::move(y_label);
  c.t_s = &a.trace.t_s;
  c.first = a.first_settled;
  for (const auto& w : a.drift_windows) c.bands.push_back({w.start_s, w.end_s});
  for (const auto& s : a.step_outs) c.markers_s.push_back(s.t_s);
  return c;
}

std::string error_table(const Anomaly& a) {
  if (!a.has_load_cell)
    return "<p>No load cell was logged (no <code>load_force_n</code> column): the force estimates "
           "cannot be "
           "compared with a measurement.</p>\n";
  if (!a.load_cell_unusable.empty())
    return "<p>The load cell was not compared with the estimates: " +
           escape_html(a.load_cell_unusable) + ".</p>\n";
  std::ostringstream h;
  const auto row = [&](const char* name, const std::optional<analysis::ErrorStats>& e) {
    h << "<tr><td>" << name << "</td><td>" << (e ? number(e->mean_abs_n) : "–") << "</td><td>"
      << (e ? number(e->rms_n) : "–") << "</td><td>" << (e ? number(e->max_abs_n) : "–")
      << "</td></tr>\n";
  };
  // The analysis's twin check (section 3) scores the start-up too: its figure may differ.
  h << "<table><tr><th>force estimate against the load cell, after the first " << number(a.settle_s)
    << " s</th><th>mean |error| [N]</th><th>RMS [N]</th>"
    << "<th>max |error| [N]</th></tr>\n";
  row(a.static_estimate_logged ? "static (paper eq. 6, as the controller logged it)"
                               : "static (paper eq. 6, recomputed)",
      a.static_error);
  row("twin (dynamic observer)", a.twin_error);
  h << "</table>\n";
  if (a.off_branch_samples)
    h << "<p>" << a.off_branch_samples
      << " samples with the phase outside the calibrated stable branch (pushed to the coupling's "
      << "peak, or leads away after a step-out) are left out of the static estimate: eq. 6 is "
      << "only defined on the branch.</p>\n";
  return h.str();
}

std::string map_figure(const Anomaly& a) {
  const auto& g = a.map_position_velocity;
  // The figure caption holds the title: none drawn into the image.
  plot::HeatMap m{"",      g.x_label, g.y_label, g.value_label, g.x_min, g.x_max,
                  g.y_min, g.y_max,   g.nx,      g.ny,          g.values};
  const std::string png = plot::heatmap_png(m, 900, 560);
  return "<figure id=\"fig-map\"><figcaption><b>" + escape_html(g.title) +
         ".</b> Mean over the samples in each cell; blank cells were not "
         "visited.</figcaption>\n<img class=\"map\" "
         "alt=\"" +
         escape_html(g.title) + "\" src=\"" + data_url_of_png_bytes(png) + "\"></figure>\n";
}

// The drift statistic where the flag judged it; before its first verdict it was not judged,
// and a line at 0 there would read as "no drift" (section 4 says why).
std::string drift_chart(const Anomaly& a) {
  const bool tracked = std::isfinite(a.drift_judged_from_s);
  if (!tracked)
    return "<p id=\"drift\"><b>Drift statistic:</b> not judged on this recording (section 4 "
           "says why), so not plotted.</p>\n";
  std::vector<double> judged = a.trace.drift_statistic;
  for (std::size_t i = 0; i < judged.size() && i < a.trace.t_s.size(); ++i)
    if (a.trace.t_s[i] < a.drift_judged_from_s)
      judged[i] = std::numeric_limits<double>::quiet_NaN();
  auto drift = chart_of(a, "drift", "Drift statistic",
                        "Change of the force estimate's error since the reference, from free moves "
                        "and a passive load revisited, over its margin: at 1 or more for 2 s the "
                        "drift warning is raised. No line before the flag first judged.",
                        "statistic [-]");
  drift.series.push_back({"drift statistic", judged});
  drift.series.push_back({"warning level", std::vector<double>(a.trace.t_s.size(), 1.0)});
  return time_chart_html(drift);
}

std::string where_section(const Anomaly& a) {
  std::ostringstream h;
  h << "<h2 id=\"where\">1. Where the twin and the machine part</h2>\n<p>Position residual "
       "(measured − twin) RMS "
    << number(a.residual_pos_rms_m * 1e6) << " µm; one encoder count is "
    << number(a.linear_count_m * 1e6) << " µm.</p>\n"
    << error_table(a);
  auto residual =
      chart_of(a, "residual", "Twin residual over time",
               "Measured minus twin-predicted nut position. Red: step-outs; shaded: drift warning.",
               "residual [µm]");
  residual.series.push_back({"position residual", scaled(a.trace.residual_pos_m, 1e6)});
  h << time_chart_html(residual);
  if (a.has_load_cell && a.load_cell_unusable.empty()) {
    auto err =
        chart_of(a, "force_error", "Force estimates minus the load cell",
                 "Error of the controller's static estimate and of the twin's observer against the "
                 "load cell (as output force).",
                 "error [N]");
    err.series.push_back(
        {"static estimate error", difference(a.trace.static_estimate_n, a.trace.output_force_n)});
    err.series.push_back(
        {"twin estimate error", difference(a.trace.twin_estimate_n, a.trace.output_force_n)});
    h << time_chart_html(err);
    h << drift_chart(a);
  }
  h << map_figure(a);
  return h.str();
}

// ---------------------------------------------------------------- section 3: the fit
std::string fit_section(const Anomaly& a, const AnalysisOutcome& o) {
  std::ostringstream h;
  h << "<h2 id=\"fit\">3. The fit before and after</h2>\n" << fit_part(o);
  auto force = chart_of(
      a, "force", "Output force: setpoint, load cell and estimates",
      "The load cell as output force (−load force), the controller's setpoint where it logged "
      "one, and the two estimates the controller has.",
      "force [N]");
  if (a.has_load_cell) force.series.push_back({"load cell", a.trace.output_force_n});
  if (any_finite(a.trace.force_set_n)) force.series.push_back({"setpoint", a.trace.force_set_n});
  force.series.push_back({"static estimate", a.trace.static_estimate_n});
  force.series.push_back({"twin estimate", a.trace.twin_estimate_n});
  h << time_chart_html(force);
  return h.str();
}

// ---------------------------------------------------------------- section 4: events
std::string step_out_table(const Anomaly& a) {
  if (a.step_outs.empty())
    return "<p>Step-outs: none, the phase stayed on the stable branch.</p>\n";
  std::ostringstream h;
  h << "<table><tr><th>step-out at [s]</th><th>leads slipped</th><th>nut position "
       "[mm]</th><th>seen by</th></tr>\n";
  for (const auto& s : a.step_outs)
    h << "<tr><td>" << seconds(s.t_s) << "</td><td>" << s.leads << "</td><td>"
      << number(s.nut_pos_m * 1e3, 5) << "</td><td>" << escape_html(s.seen_by) << "</td></tr>\n";
  return h.str() + "</table>\n";
}

std::string window_table(const std::vector<analysis::TimeWindow>& w, const std::string& what) {
  std::string h = "<table><tr><th>" + what + " from [s]</th><th>to [s]</th></tr>\n";
  for (const auto& x : w)
    h += "<tr><td>" + seconds(x.start_s) + "</td><td>" + seconds(x.end_s) + "</td></tr>\n";
  return h + "</table>\n";
}

/// Why the drift flag never judged this recording; empty when it judged (or warned).
std::string drift_not_judged(const Anomaly& a) {
  if (!a.drift_windows.empty() || std::isfinite(a.drift_judged_from_s)) return {};
  if (a.drift_observability == 0) return "no stretch with a known external force";
  if (a.drift_observability == 1)
    return "too few known-force stretches, free moves or a passive load revisited, to form the "
           "reference";
  return "the known-force stretches were compared with their reference, too few to measure how "
         "much they scatter";
}

std::string events_section(const Anomaly& a, const AnalysisOutcome& o) {
  std::ostringstream h;
  h << "<h2 id=\"events\">4. Events</h2>\n" << step_out_table(a);
  if (!a.step_out_warnings.empty())
    h << "<p>The twin predicted a step-out (its look-ahead crossed ±π/2) in "
      << a.step_out_warnings.size()
      << " window(s), the first from t = " << seconds(a.step_out_warnings.front().start_s)
      << " s.</p>\n";
  if (const std::string why = drift_not_judged(a); !why.empty())
    h << "<p>Drift not judged: " << escape_html(why)
      << " (the flag judges free moves and a passive load the force loop revisits, and never "
         "reads the load cell).</p>\n";
  else if (a.drift_windows.empty())
    h << "<p>Drift warnings: none from t = " << seconds(a.drift_judged_from_s)
      << " s, when it was first judged, to the end (the statistic reached "
      << number(a.max_drift_statistic) << " of 1); not judged before.</p>\n";
  else
    h << window_table(a.drift_windows, "drift warning")
      << "<p>The warning is latched: the calibration no longer "
      << "matches the actuator.</p>\n";
  h << analysis_events(o);
  auto motion =
      chart_of(a, "motion", "Nut position",
               "With the position setpoint where the controller logged one.", "position [mm]");
  motion.series.push_back({"nut position", scaled(a.trace.nut_pos_m, 1e3)});
  if (any_finite(a.trace.pos_set_m))
    motion.series.push_back({"setpoint", scaled(a.trace.pos_set_m, 1e3)});
  h << time_chart_html(motion);
  auto phase = chart_of(
      a, "phase", "Phase difference",
      "φ = θ − 2πp/L and the edges of the stable branch (±π/2): beyond them the nut can step out.",
      "phase [rad]");
  phase.series.push_back({"phase", a.trace.phase_rad});
  phase.series.push_back({"+π/2", std::vector<double>(a.trace.t_s.size(), std::numbers::pi / 2)});
  phase.series.push_back({"−π/2", std::vector<double>(a.trace.t_s.size(), -std::numbers::pi / 2)});
  h << time_chart_html(phase);
  return h.str();
}

// ---------------------------------------------------------------- JSON
Json json_of(const std::string& recording, const Anomaly& a, const AnalysisOutcome& o,
             const std::string& headline) {
  Json J;
  J["recording"] = recording;
  J["samples"] = a.trace.t_s.size();
  J["duration_s"] = a.duration_s;
  J["sample_rate_hz"] = a.sample_rate_hz;
  J["settle_s"] = a.settle_s;
  J["headline"] = headline;
  J["step_outs"] = Json::array();
  for (const auto& s : a.step_outs)
    J["step_outs"].push_back(
        {{"t_s", s.t_s}, {"leads", s.leads}, {"source", s.seen_by}, {"nut_pos_m", s.nut_pos_m}});
  const std::string drift_why = drift_not_judged(a);
  J["drift_judged"] = drift_why.empty();
  J["drift_not_judged_reason"] = drift_why;
  J["drift_windows"] = Json::array();
  for (const auto& w : a.drift_windows)
    J["drift_windows"].push_back({{"start_s", w.start_s}, {"end_s", w.end_s}});
  J["step_out_warning_windows"] = a.step_out_warnings.size();
  J["twin_residual_pos_rms_m"] = a.residual_pos_rms_m;
  J["static_estimate_off_branch_samples"] = a.off_branch_samples;
  const auto stats = [](const std::optional<analysis::ErrorStats>& e) {
    return e ? Json{{"mean_abs_n", e->mean_abs_n}, {"rms_n", e->rms_n}, {"max_abs_n", e->max_abs_n}}
             : Json();
  };
  J["force_error"] = a.has_load_cell && a.load_cell_unusable.empty()
                         ? Json{{"static", stats(a.static_error)}, {"twin", stats(a.twin_error)}}
                         : Json();
  Json v;
  if (o.status == AnalysisOutcome::Status::done) {
    const auto& R = o.result->findings;
    v = {{"status", "done"},
         {"headline", o.result->headline},
         {"conclusion", R.conclusion},
         {"effects", Json::array()},
         {"baseline_relative_error_pct", R.baseline.relative_error_pct},
         {"final_relative_error_pct", R.final_fit.relative_error_pct}};
    for (const auto& e : R.effects)
      v["effects"].push_back({{"id", e.id}, {"parameters", parameters_json(e.parameters)}});
  } else {
    v = {{"status", o.status == AnalysisOutcome::Status::skipped ? "skipped" : "not possible"},
         {"reason", o.reason}};
  }
  J["analysis"] = v;
  return J;
}

void write_text(const fs::path& path, const std::string& text) {
  write_file_atomically(path.string(), text);
}

}  // namespace

std::string anomaly_headline(const Anomaly& a, const AnalysisOutcome& o) {
  std::vector<std::string> findings, not_judged;
  if (!a.step_outs.empty())
    findings.push_back(std::to_string(a.step_outs.size()) + " step-out event(s)");
  if (!a.drift_windows.empty())
    findings.push_back(
        "calibration drift detected from t = " + number(a.drift_windows.front().start_s) + " s");
  if (const std::string why = drift_not_judged(a); !why.empty())
    not_judged.push_back("drift (" + why + ")");
  if (a.load_cell_constant_n)
    not_judged.push_back("force estimate (the load cell reads a constant " +
                         number(*a.load_cell_constant_n) + " N: check its wiring)");
  else if (!a.load_cell_unusable.empty())
    not_judged.emplace_back(
        "force estimate (load_force_n is not the load in newtons: see analysis)");
  else if (!a.static_error)
    not_judged.emplace_back(a.has_load_cell ? "force estimate (no settled sample where both the "
                                              "estimate and load_force_n are numbers)"
                                            : "force estimate (no load_force_n column)");
  else if (a.static_error->mean_abs_n > std::max(kStaticAttention_n, a.static_friction_band_n))
    findings.push_back("static force estimate off by " + number(a.static_error->mean_abs_n) +
                       " N on average, more than the model's friction (" +
                       number(a.static_friction_band_n) + " N) explains");
  if (o.status != AnalysisOutcome::Status::done) {
    not_judged.push_back("analysis (" + (o.reason.empty() ? std::string("not run") : o.reason) +
                         ")");
  } else {
    std::string h = o.result->headline;
    // Laws the analysis could not judge follow its conclusion: "…; not judged: mass_error (…)".
    const std::string unjudged = std::string("; ") + analysis::kNotJudged;
    if (const auto cut = h.find(unjudged); cut != std::string::npos) {
      not_judged.push_back("analysis (" + h.substr(cut + unjudged.size()) + ")");
      h.resize(cut);
    }
    if (h.rfind(analysis::kNotJudged, 0) == 0)
      not_judged.push_back("analysis (" + h.substr(std::string(analysis::kNotJudged).size()) + ")");
    else if (h.rfind("nothing missing", 0) != 0)
      findings.push_back(h);
  }
  const auto joined = [](const std::vector<std::string>& parts) {
    std::string s;
    for (std::size_t k = 0; k < parts.size(); ++k) s += (k ? "; " : "") + parts[k];
    return s;
  };
  // "No anomaly" is said only of what was judged; what was not is named.
  const std::string unjudged = not_judged.empty() ? "" : "not judged: " + joined(not_judged);
  if (findings.empty()) return unjudged.empty() ? "no anomaly found" : unjudged;
  return "attention: " + joined(findings) + (unjudged.empty() ? "" : "; " + unjudged);
}

void write_anomaly_report(const std::string& out_dir, const std::string& recording,
                          const Anomaly& a, const AnalysisOutcome& o) {
  fs::create_directories(out_dir);
  const std::string headline = anomaly_headline(a, o);
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head>"
    << page_head("maglead anomaly report: " + fs::path(recording).filename().string())
    << "</head>\n<body>\n<h1>Twin versus actual: anomaly report</h1>\n<p>Recording <code title=\""
    << escape_html(recording) << "\">" << escape_html(fs::path(recording).filename().string())
    << "</code>: " << a.trace.t_s.size() << " samples, " << number(a.duration_s, 4) << " s at "
    << number(a.sample_rate_hz, 4) << " Hz. The first " << number(a.settle_s)
    << " s are the start-up "
    << "(the servo aligning the screw, the estimators settling) and are neither plotted nor "
       "scored.</p>\n"
    << "<p class=\""
    << (headline == "no anomaly found"         ? "ok"
        : headline.rfind("not judged", 0) == 0 ? "unjudged"
                                               : "bad")
    << "\" id=\"headline\"><b>" << escape_html(headline)
    << "</b></p>\n<p class=\"hint\">Plots: drag to zoom, shift-drag to pan, double-click "
    << "to reset; every time plot follows the others. Values show on hover.</p>\n"
    << where_section(a) << physics_section(o, 2) << fit_section(a, o) << events_section(a, o)
    << time_chart_tail() << "</body></html>\n";
  write_text(fs::path(out_dir) / "index.html", h.str());
  write_text(fs::path(out_dir) / "report.json", json_of(recording, a, o, headline).dump(2) + "\n");
}

}  // namespace maglead::report
