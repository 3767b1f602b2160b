// The output of `maglead analyze`: analysis.json for machines, model_corrected.toml, and for
// people index.html, the analysis part of `report`'s page (analysis_part.hpp) on a page of its own.
#include "maglead/report/analysis_page.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "analysis_part.hpp"
#include "maglead/effects/axis_kind.hpp"
#include "maglead/fileio/atomic_file.hpp"
#include "maglead/report/analysis_json.hpp"
#include "maglead/report/html.hpp"
#include "maglead/report/time_chart.hpp"

namespace maglead::report {
namespace {

namespace fs = std::filesystem;

void write_text(const fs::path& path, const std::string& text) {
  write_file_atomically(path.string(), text);  // a crash never leaves half a page or model
}

std::string intro(const analysis::Findings& F) {
  const std::string file = fs::path(F.recording).filename().string();
  return "<p>Recording <code title=\"" + escape_html(F.recording) + "\">" + escape_html(file) +
         "</code>: " + std::to_string(F.samples) + " samples, " + std::to_string(F.samples_used) +
         " used by the fit; system <b>" + escape_html(F.system) + "</b>.</p>\n<p class=\"" +
         conclusion_class(F) + "\" id=\"conclusion\"><b>" + escape_html(F.conclusion) +
         "</b></p>\n<p class=\"hint\">Plots: drag to zoom, shift-drag to pan, double-click to "
         "reset. Values show on hover.</p>\n";
}

std::string validation_table(const analysis::Findings& F) {
  if (F.validation.size() < 2) return "";
  std::string h = "<table><tr><th>model</th><th>held-out RMS [" +
                  std::string(effects::drive_unit_of_system(F.system)) +
                  "]</th><th>held-out relative error [%]</th></tr>\n";
  for (const auto& v : F.validation)
    h += "<tr><td>" + escape_html(v.model) + "</td><td>" + number(v.heldout_rms_n) + "</td><td>" +
         number(v.heldout_relative_error_pct) + "</td></tr>\n";
  return h + "</table>\n";
}

std::string twin_text(const analysis::Findings& F) {
  if (!F.twin_simulation) return "";
  const auto& t = *F.twin_simulation;
  if (!t.available) return "<p>Twin re-simulation: not run (" + escape_html(t.reason) + ").</p>\n";
  return "<p>Twin re-simulation from measured states: position error RMS " +
         number(t.baseline_rms_position_error_m * 1e6) + " µm with the model as configured, " +
         number(t.corrected_rms_position_error_m * 1e6) + " µm corrected, over " +
         std::to_string(t.windows) + " windows of " + number(t.horizon_s) + " s.</p>\n";
}

std::string method_text(const analysis::Findings& F) {
  const auto& m = F.method;
  return "<p class=\"meaning\">Method: " + escape_html(m.domain) + "; " + escape_html(m.filter) +
         "; decimation " + std::to_string(m.decimation) + "; " + escape_html(m.selection) + "; " +
         escape_html(m.moving_only) + ".</p>\n";
}

/// The headline at the top, coloured as the anomaly report's: found or misfit, nothing missing,
/// not judged.
std::string headline_paragraph(const std::string& headline) {
  // "nothing missing: …; not judged: …" (headline_of) is no all-clear either.
  const bool nothing = headline.rfind("nothing missing", 0) == 0;
  const bool unjudged =
      headline.rfind("not judged", 0) == 0 ||
      (nothing && headline.find(std::string("; ") + analysis::kNotJudged) != std::string::npos);
  const char* cls = unjudged ? "unjudged" : nothing ? "ok" : "bad";
  return std::string("<p class=\"") + cls + "\" id=\"headline\"><b>" + escape_html(headline) +
         "</b></p>\n";
}

std::string page(const AnalysisOutcome& o) {
  const auto& F = o.result->findings;
  // An axis (linear or rotary) is compared with its model; only the actuator has a twin.
  const bool axis = effects::axis_kind_of_system(F.system) != nullptr;
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head>"
    << page_head("maglead analysis: " + fs::path(F.recording).filename().string())
    << "</head>\n<body>\n<h1>" << (axis ? "Model" : "Twin") << " versus recording: analysis</h1>\n"
    << headline_paragraph(o.result->headline) << intro(F) << physics_section(o, 1)
    << "<h2 id=\"fit\">2. The fit before and after</h2>\n"
    << fit_part(o) << validation_table(F) << twin_text(F)
    << "<p>The corrected model is written to <code>model_corrected.toml</code>.</p>\n"
    << "<h2 id=\"events\">3. Events</h2>\n";
  const std::string events = analysis_events(o);
  h << (events.empty() ? "<p>No " + std::string(axis_words(F).quantity) + " pulses.</p>\n"
                       : events);
  const std::string figures = analysis_figures(o);
  if (!figures.empty()) h << "<h2 id=\"maps\">4. Maps and figures</h2>\n" << figures;
  h << method_text(F) << time_chart_tail() << "</body></html>\n";
  return h.str();
}

}  // namespace

void write_analysis_outputs(const analysis::AnalysisResult& r, const std::string& out_dir) {
  fs::create_directories(out_dir);
  write_text(fs::path(out_dir) / "analysis.json", analysis_json(r).dump(2) + "\n");
  analysis::save_model((fs::path(out_dir) / "model_corrected.toml").string(), r.corrected,
                       "model corrected by maglead analyze from " + r.findings.recording);
  AnalysisOutcome outcome;
  outcome.status = AnalysisOutcome::Status::done;
  outcome.result = r;
  write_text(fs::path(out_dir) / "index.html", page(outcome));
}

}  // namespace maglead::report
