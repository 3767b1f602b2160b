// maglead report: the twin-versus-actual anomaly report for an operator. Replays a recording
// through the controller's TwinMonitor (step-outs, drift, residuals), compares the force
// estimates with the load cell where one was logged, runs the analysis library for the verdict,
// and writes one self-contained HTML page (plots embedded as base64 PNG) plus report.json.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>

#include "cli_common.hpp"
#include "maglead/analysis/analysis.hpp"
#include "maglead/physics/estimator.hpp"
#include "maglead/tools/plot.hpp"
#include "maglead/twin/monitor.hpp"

namespace maglead::cli {
namespace {

using Json = nlohmann::ordered_json;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string base64(const std::string& in) {
  static const char* tbl = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(in[i]) << 16) | (static_cast<unsigned char>(in[i + 1]) << 8) |
                       static_cast<unsigned char>(in[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out += tbl[(v >> s) & 63];
  }
  if (i < in.size()) {
    unsigned v = static_cast<unsigned char>(in[i]) << 16;
    if (i + 1 < in.size()) v |= static_cast<unsigned char>(in[i + 1]) << 8;
    out += tbl[(v >> 18) & 63];
    out += tbl[(v >> 12) & 63];
    out += i + 1 < in.size() ? tbl[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

std::string read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

std::string esc(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<') o += "&lt;";
    else if (c == '>') o += "&gt;";
    else if (c == '&') o += "&amp;";
    else if (c == '"') o += "&quot;";
    else o += c;
  }
  return o;
}

std::string num(double v, int prec = 3) {
  if (!std::isfinite(v)) return "–";
  std::ostringstream o;
  o.precision(prec);
  o << v;
  return o.str();
}

struct ErrorStats {
  double mean_abs_n = kNaN, rms_n = kNaN, max_abs_n = kNaN;
  std::size_t samples = 0;
};
ErrorStats stats(const std::vector<double>& err) {
  ErrorStats s{0, 0, 0, 0};
  for (double e : err) {
    if (!std::isfinite(e)) continue;
    s.mean_abs_n += std::abs(e);
    s.rms_n += e * e;
    s.max_abs_n = std::max(s.max_abs_n, std::abs(e));
    ++s.samples;
  }
  if (!s.samples) return {};
  s.mean_abs_n /= static_cast<double>(s.samples);
  s.rms_n = std::sqrt(s.rms_n / static_cast<double>(s.samples));
  return s;
}

/// Contiguous [start, end] time intervals where flag is set.
std::vector<std::pair<double, double>> windows(const std::vector<double>& t, const std::vector<bool>& flag) {
  std::vector<std::pair<double, double>> w;
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (!flag[i]) continue;
    if (i > 0 && flag[i - 1]) w.back().second = t[i];
    else w.emplace_back(t[i], t[i]);
  }
  return w;
}

void add_report(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "report", "Twin-versus-actual anomaly report of a recording: step-outs, drift windows, force-estimate "
                "error against the load cell, twin residual, analysis verdict; one HTML page with plots");
  struct Opts {
    std::string recording, out, config = default_config_dir(), calibration, model;
    bool no_analysis = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("--recording", o->recording, "mls-recording/1 (t_s, screw or motor angle, nut_pos_m; "
                                                 "load_force_n, out_force_est_n, force_set_n if logged)")
      ->required();
  cmd->add_option("--out", o->out, "Output directory (index.html, report.json, the PNGs)")->required();
  cmd->add_option("--config", o->config, "Configuration directory")->capture_default_str();
  cmd->add_option("--calibration", o->calibration, "Force calibration (default: CONFIG/calibration.toml)");
  cmd->add_option("--model", o->model, "Baseline model for the analysis (default: CONFIG/model.toml)");
  cmd->add_flag("--no-analysis", o->no_analysis, "Skip the analysis library's verdict (quicker)");
  cmd->callback([o] {
    namespace fs = std::filesystem;
    const ActuatorParams act = load_actuator_or_default(o->config);
    const ForceCalibration cal =
        load_calibration(o->calibration.empty() ? config_file(o->config, "calibration.toml") : o->calibration);
    const Recording rec = read_recording(o->recording, {"t_s", "nut_pos_m"});
    const auto screw = screw_angle_of(rec, act);
    const auto& t = rec.column("t_s");
    const auto& pos = rec.column("nut_pos_m");
    const std::size_t n = t.size();
    if (n < 2) throw RecordingError(o->recording + ": needs at least two samples");
    const double period = (t.back() - t.front()) / static_cast<double>(n - 1);
    if (!(period > 0)) throw RecordingError(o->recording + ": t_s does not advance");
    fs::create_directories(o->out);

    // ---- twin replay: the TwinMonitor the controller runs, fed row by row at the recording's rate.
    twin::TwinMonitorConfig tc = twin::load_monitor_config(o->config);
    tc.actuator = act;
    tc.actuator.sample_rate_hz = 1.0 / period;
    tc.integrator.max_step_s = period;
    tc.calibration = cal;
    twin::TwinMonitor mon(tc);
    mon.reset(t[0], screw[0], pos[0]);
    const std::vector<double>* fset = rec.has("force_set_n") ? &rec.column("force_set_n") : nullptr;
    // The load cell feeds the drift detector, as live and in twin-check.
    const std::vector<double>* lc = rec.has("load_force_n") ? &rec.column("load_force_n") : nullptr;
    std::vector<double> res_pos_um(n), res_force_n(n), drift_stat(n), dyn_n(n), phase(n);
    std::vector<bool> drift(n), warn(n);
    Json step_outs = Json::array();
    int slips = 0;
    Progress bar("report: twin replay");
    for (std::size_t i = 0; i < n; ++i) {
      const auto out = mon.step({t[i], screw[i], pos[i], fset ? (*fset)[i] : kNaN, lc ? (*lc)[i] : kNaN});
      res_pos_um[i] = out.residual_pos_m * 1e6;
      res_force_n[i] = out.residual_force_n;
      drift_stat[i] = out.drift_statistic;
      dyn_n[i] = out.dynamic_output_force_est_n;
      phase[i] = out.phase_rad;
      drift[i] = out.drift_warning;
      warn[i] = out.step_out_warning;
      if (out.slips != slips) {
        step_outs.push_back({{"t_s", t[i]}, {"leads", out.slips - slips}, {"source", "twin replay"},
                             {"nut_pos_m", pos[i]}});
        slips = out.slips;
      }
      if (i % 512 == 0) bar(static_cast<double>(i) / static_cast<double>(n));
    }
    bar.done();
    // What the controller itself logged, where the recording has it (maglead record).
    if (rec.has("step_out_count")) {
      const auto& c = rec.column("step_out_count");
      for (std::size_t i = 1; i < n; ++i)
        if (std::isfinite(c[i]) && std::isfinite(c[i - 1]) && c[i] > c[i - 1])
          step_outs.push_back({{"t_s", t[i]}, {"leads", c[i] - c[i - 1]}, {"source", "controller"},
                               {"nut_pos_m", pos[i]}});
    }
    const auto drift_windows = windows(t, drift);
    const auto warn_windows = windows(t, warn);

    // ---- force estimates against the load cell (output force = −load force).
    const bool has_load = rec.has("load_force_n");
    std::vector<double> measured(n, kNaN), static_est(n), err_static(n, kNaN), err_twin(n, kNaN);
    const bool logged_estimate = rec.has("out_force_est_n");
    if (logged_estimate) {
      static_est = rec.column("out_force_est_n");
    } else {
      StaticForceEstimator est(cal, act.coulomb_n, 1e-5);
      EncoderVelocityEstimator vel(period, act.linear_count_m);
      for (std::size_t i = 0; i < n; ++i) {
        const double v = i == 0 ? (vel.reset(pos[i]), 0.0) : vel.update(pos[i]);
        static_est[i] = est.output_force_n(phase_rad(screw[i], pos[i], act.lead_m), v);
      }
    }
    // Eq. 6 means nothing off the stable branch (after a step-out φ sits leads away): those
    // samples are left out of the static estimate rather than scored at millions of newtons.
    std::size_t off_branch = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (phase[i] < cal.stable_min_rad || phase[i] > cal.stable_max_rad) {
        static_est[i] = kNaN;
        ++off_branch;
      }
    }
    if (has_load) {
      const auto& load = rec.column("load_force_n");
      for (std::size_t i = 0; i < n; ++i) {
        measured[i] = -load[i];
        err_static[i] = static_est[i] - measured[i];
        err_twin[i] = dyn_n[i] - measured[i];
      }
    }
    const ErrorStats es = stats(err_static), et = stats(err_twin);
    const double rms_res_um = [&] {
      double s = 0;
      for (double r : res_pos_um) s += r * r;
      return std::sqrt(s / static_cast<double>(n));
    }();

    // ---- figures, written beside the page and embedded in it.
    struct Fig {
      std::string file, title, caption;
    };
    std::vector<Fig> figs;
    const auto save = [&](const std::string& file, const std::string& title, const std::string& caption,
                          const std::vector<plot::Panel>& panels) {
      plot::save_panels_png((fs::path(o->out) / file).string(), panels, 1100, 260);
      figs.push_back({file, title, caption});
    };
    std::vector<double> pos_mm(n);
    for (std::size_t i = 0; i < n; ++i) pos_mm[i] = pos[i] * 1e3;
    std::vector<double> half_pi_hi(n, std::numbers::pi / 2), half_pi_lo(n, -std::numbers::pi / 2);
    save("overview.png", "Motion and phase",
         "Nut position, and the phase difference with the edges of the stable branch (±π/2): beyond them the "
         "nut can step out.",
         {{"Nut position", "time [s]", "[mm]", {{"nut position", t, pos_mm}}},
          {"Phase difference", "time [s]", "[rad]",
           {{"phase (twin replay)", t, phase}, {"+pi/2", t, half_pi_hi}, {"-pi/2", t, half_pi_lo}}}});
    std::vector<double> one(n, 1.0);
    save("twin_residual.png", "Twin residual over time",
         "Measured minus twin-predicted nut position, the force residual (dynamic minus static estimate) and the "
         "drift statistic (|g - g_ref| / margin; 1, sustained for 2 s, raises the drift warning).",
         {{"Position residual (measured - twin)", "time [s]", "[um]", {{"position residual", t, res_pos_um}}},
          {"Force residual (dynamic - static estimate)", "time [s]", "[N]", {{"force residual", t, res_force_n}}},
          {"Drift statistic", "time [s]", "[-]", {{"|g - g_ref| / margin", t, drift_stat}, {"margin", t, one}}}});
    if (has_load)
      save("force_error.png", "Force estimate against the load cell",
           "Output force from the load cell (−load force) against the controller's static estimate (paper eq. 6)"
           " and the twin's dynamic estimate; below, their errors.",
           {{"Output force", "time [s]", "[N]",
             {{"load cell", t, measured},
              {logged_estimate ? "static estimate (logged)" : "static estimate (recomputed)", t, static_est},
              {"twin dynamic estimate", t, dyn_n}}},
            {"Estimation error (estimate - load cell)", "time [s]", "[N]",
             {{"static", t, err_static}, {"twin", t, err_twin}}}});

    // ---- the analysis library's verdict.
    Json verdict;
    std::string analysis_html;
    if (o->no_analysis) {
      verdict = {{"status", "skipped"}, {"reason", "--no-analysis"}};
    } else {
      try {
        std::string model_path = o->model;
        if (model_path.empty() && fs::exists(config_file(o->config, "model.toml")))
          model_path = config_file(o->config, "model.toml");
        const auto model = model_path.empty() ? analysis::actuator_model_from_config(act)
                                              : analysis::load_model(model_path);
        analysis::AnalysisOptions ao;
        std::unique_ptr<Progress> abar;
        std::string stage;
        ao.progress = [&](const std::string& st, double f) {
          if (st != stage) {
            if (abar) abar->done();
            abar = std::make_unique<Progress>("report: analysis: " + st);
            stage = st;
          }
          (*abar)(f);
        };
        const auto result = analysis::analyze_recording(rec, model, cal, act, ao);
        if (abar) abar->done();
        const auto& J = result.json;
        verdict = {{"status", "done"},
                   {"conclusion", J.value("conclusion", "")},
                   {"baseline_relative_error_pct", J["baseline"].value("relative_error_pct", kNaN)},
                   {"final_relative_error_pct", J["final"].value("relative_error_pct", kNaN)},
                   {"effects", Json::array()}};
        analysis_html += "<p><b>" + esc(J.value("conclusion", "")) + "</b>. Baseline model relative force error " +
                         num(J["baseline"].value("relative_error_pct", kNaN)) + " %, after adding the effects " +
                         num(J["final"].value("relative_error_pct", kNaN)) + " %.</p>\n";
        if (!J["effects"].empty()) {
          analysis_html += "<table><tr><th>effect</th><th>parameters</th><th>where / finding</th></tr>\n";
          for (const auto& e : J["effects"]) {
            const std::string id = e.value("id", "");
            verdict["effects"].push_back({{"id", id}, {"parameters", e.value("parameters", nlohmann::json::object())}});
            std::string where = e.contains("where") && e["where"].is_string() ? e["where"].get<std::string>() : "";
            if (e.contains("finding")) where += (where.empty() ? "" : "; ") + e["finding"].get<std::string>();
            analysis_html += "<tr><td>" + esc(id) + "</td><td>" + esc(e.value("parameters", nlohmann::json::object()).dump()) +
                             "</td><td>" + esc(where) + "</td></tr>\n";
          }
          analysis_html += "</table>\n";
        }
        for (const auto& w : result.where) analysis_html += "<p>where: " + esc(w) + "</p>\n";
      } catch (const std::exception& e) {
        verdict = {{"status", "not possible"}, {"reason", e.what()}};
        analysis_html = "<p>The analysis could not run on this recording: " + esc(e.what()) + "</p>\n";
      }
    }

    // ---- summary and page.
    std::vector<std::string> findings;
    if (!step_outs.empty()) findings.push_back(std::to_string(step_outs.size()) + " step-out event(s)");
    if (!drift_windows.empty())
      findings.push_back("calibration drift detected from t = " + num(drift_windows.front().first) + " s");
    if (has_load && std::isfinite(es.mean_abs_n) && es.mean_abs_n > 3.0)
      findings.push_back("static force estimate off by " + num(es.mean_abs_n) + " N on average");
    if (verdict.value("status", "") == "done" && !verdict["effects"].empty())
      findings.push_back("analysis: " + verdict.value("conclusion", ""));
    const std::string headline = findings.empty() ? "no anomaly found" : "attention: " + [&] {
      std::string s;
      for (const auto& f : findings) s += (s.empty() ? "" : "; ") + f;
      return s;
    }();

    Json J;
    J["recording"] = o->recording;
    J["samples"] = n;
    J["duration_s"] = t.back() - t.front();
    J["sample_rate_hz"] = 1.0 / period;
    J["headline"] = headline;
    J["step_outs"] = step_outs;
    J["drift_windows"] = Json::array();
    for (const auto& [a, b] : drift_windows) J["drift_windows"].push_back({{"start_s", a}, {"end_s", b}});
    J["step_out_warning_windows"] = warn_windows.size();
    J["twin_residual_pos_rms_m"] = rms_res_um * 1e-6;
    J["static_estimate_off_branch_samples"] = off_branch;
    if (has_load)
      J["force_error"] = {{"static", {{"mean_abs_n", es.mean_abs_n}, {"rms_n", es.rms_n}, {"max_abs_n", es.max_abs_n}}},
                          {"twin", {{"mean_abs_n", et.mean_abs_n}, {"rms_n", et.rms_n}, {"max_abs_n", et.max_abs_n}}}};
    else
      J["force_error"] = nullptr;
    J["analysis"] = verdict;
    J["figures"] = Json::array();
    for (const auto& f : figs) J["figures"].push_back(f.file);
    std::ofstream(fs::path(o->out) / "report.json") << J.dump(2) << "\n";

    std::ostringstream h;
    h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<title>maglead anomaly report: "
      << esc(fs::path(o->recording).filename().string()) << "</title>\n<style>\n"
      << "body{font-family:sans-serif;max-width:1150px;margin:1em auto;color:#222}"
         "h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ccc;margin-top:1.5em}"
         "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}"
         ".ok{background:#e6f4e6;padding:.6em}.bad{background:#fbe9e7;padding:.6em}img{max-width:100%}"
         "figcaption{color:#555;font-size:.9em}\n</style></head>\n<body>\n";
    h << "<h1>Twin versus actual: anomaly report</h1>\n<p>Recording <code>" << esc(o->recording) << "</code>: " << n
      << " samples, " << num(t.back() - t.front(), 4) << " s at " << num(1.0 / period, 4) << " Hz.</p>\n";
    h << "<p class=\"" << (findings.empty() ? "ok" : "bad") << "\" id=\"headline\"><b>" << esc(headline)
      << "</b></p>\n";
    h << "<h2>Step-out events</h2>\n";
    if (step_outs.empty()) {
      h << "<p>None: the phase stayed on the stable branch.</p>\n";
    } else {
      h << "<table><tr><th>time [s]</th><th>leads slipped</th><th>nut position [mm]</th><th>seen by</th></tr>\n";
      for (const auto& e : step_outs)
        h << "<tr><td>" << num(e["t_s"].get<double>(), 6) << "</td><td>" << e["leads"].dump() << "</td><td>"
          << num(e["nut_pos_m"].get<double>() * 1e3, 5) << "</td><td>" << e["source"].get<std::string>()
          << "</td></tr>\n";
      h << "</table>\n";
    }
    if (!warn_windows.empty())
      h << "<p>The twin predicted a step-out (look-ahead crossing ±π/2) in " << warn_windows.size()
        << " window(s).</p>\n";
    h << "<h2>Drift windows</h2>\n";
    if (drift_windows.empty()) {
      h << "<p>None: the drift statistic stayed below its threshold (max " << num(*std::max_element(drift_stat.begin(), drift_stat.end()))
        << ").</p>\n";
    } else {
      h << "<table><tr><th>from [s]</th><th>to [s]</th></tr>\n";
      for (const auto& [a, b] : drift_windows) h << "<tr><td>" << num(a, 6) << "</td><td>" << num(b, 6) << "</td></tr>\n";
      h << "</table><p>The drift warning is latched: the calibration no longer matches the actuator.</p>\n";
    }
    h << "<h2>Force estimate against the load cell</h2>\n";
    if (has_load) {
      h << "<table><tr><th>estimate</th><th>mean |error| [N]</th><th>RMS [N]</th><th>max |error| [N]</th></tr>\n"
        << "<tr><td>static (paper eq. 6" << (logged_estimate ? ", as logged" : ", recomputed") << ")</td><td>"
        << num(es.mean_abs_n) << "</td><td>" << num(es.rms_n) << "</td><td>" << num(es.max_abs_n) << "</td></tr>\n"
        << "<tr><td>twin dynamic observer</td><td>" << num(et.mean_abs_n) << "</td><td>" << num(et.rms_n)
        << "</td><td>" << num(et.max_abs_n) << "</td></tr></table>\n";
      if (off_branch)
        h << "<p>" << off_branch << " samples with the phase off the stable branch (after a step-out) are left "
          << "out of the static estimate: eq. 6 is only defined on the branch.</p>\n";
    } else {
      h << "<p>No load cell was logged (no <code>load_force_n</code> column): nothing to compare with.</p>\n";
    }
    h << "<h2>Twin residual</h2>\n<p>RMS position residual " << num(rms_res_um) << " µm (one encoder count is "
      << num(act.linear_count_m * 1e6) << " µm).</p>\n";
    h << "<h2>Analysis verdict</h2>\n" << analysis_html;
    if (o->no_analysis) h << "<p>Skipped (--no-analysis).</p>\n";
    h << "<h2>Plots</h2>\n";
    for (const auto& f : figs)
      h << "<figure><figcaption><b>" << esc(f.title) << ".</b> " << esc(f.caption)
        << "</figcaption>\n<img alt=\"" << esc(f.title) << "\" src=\"data:image/png;base64,"
        << base64(read_file((fs::path(o->out) / f.file).string())) << "\"></figure>\n";
    // A marker for automated checks (and a note for people) that every image decoded.
    h << "<p id=\"image-status\">images not checked (JavaScript off)</p>\n<script>\n"
         "window.addEventListener('load',function(){var im=Array.prototype.slice.call(document.images);"
         "var ok=im.length>0&&im.every(function(i){return i.complete&&i.naturalWidth>0;});"
         "document.body.setAttribute('data-images',ok?'ok':'broken');"
         "document.getElementById('image-status').textContent=ok?('all '+im.length+' plots loaded'):"
         "'some plots failed to load';});\n</script>\n</body></html>\n";
    const auto page = (fs::path(o->out) / "index.html").string();
    std::ofstream(page) << h.str();
    std::printf("%s\n", headline.c_str());
    std::printf("step-outs: %zu, drift windows: %zu, twin position residual RMS %.1f um\n", step_outs.size(),
                drift_windows.size(), rms_res_um);
    if (has_load)
      std::printf("force error against load cell: static %.2f N, twin %.2f N (mean absolute)\n", es.mean_abs_n,
                  et.mean_abs_n);
    std::printf("analysis: %s\n", verdict.value("status", "").c_str());
    std::printf("wrote %s, report.json and %zu plots\n", page.c_str(), figs.size());
  });
}

MAGLEAD_COMMAND(87, add_report);

}  // namespace
}  // namespace maglead::cli
