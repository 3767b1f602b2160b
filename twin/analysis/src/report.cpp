// analysis.json for machines, report.html (figures embedded as base64) for people.
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "maglead/analysis/analysis.hpp"

namespace maglead::analysis {
namespace {

std::string base64_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  const std::string in((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  static const char* tbl = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(in[i]) << 16) |
                       (static_cast<unsigned char>(in[i + 1]) << 8) | static_cast<unsigned char>(in[i + 2]);
    out += tbl[(v >> 18) & 63];
    out += tbl[(v >> 12) & 63];
    out += tbl[(v >> 6) & 63];
    out += tbl[v & 63];
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

std::string esc(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<') o += "&lt;";
    else if (c == '>') o += "&gt;";
    else if (c == '&') o += "&amp;";
    else o += c;
  }
  return o;
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
    s += it.key() + " = " + (it.value().is_number() ? num(it.value().get<double>()) : it.value().dump());
  }
  return s;
}

}  // namespace

void write_outputs(const AnalysisResult& r, const std::string& out_dir) {
  namespace fs = std::filesystem;
  fs::create_directories(out_dir);
  const auto path = [&](const std::string& f) { return (fs::path(out_dir) / f).string(); };
  {
    std::ofstream j(path("analysis.json"));
    j << r.json.dump(2) << "\n";
    if (!j) throw std::runtime_error("cannot write " + path("analysis.json"));
  }
  save_model(path("model_corrected.toml"), r.corrected,
             "model corrected by maglead analyze from " + r.json.value("recording", std::string()));
  for (const auto& f : r.figures) {
    if (f.heat)
      plot::save_heatmap_png(path(f.file), f.heatmap);
    else
      plot::save_panels_png(path(f.file), f.panels, 1100, 300);
  }
  const auto& J = r.json;
  std::ostringstream h;
  h << "<!doctype html><html><head><meta charset=\"utf-8\"><title>maglead analyze</title><style>"
       "body{font-family:sans-serif;max-width:1150px;margin:auto}table{border-collapse:collapse}"
       "td,th{border:1px solid #aaa;padding:3px 8px}img{max-width:100%}.alt{color:#a40}</style>"
       "</head><body>\n";
  h << "<h1>Twin versus recording</h1><p>Recording <code>" << esc(J["recording"]) << "</code> ("
    << J["samples"] << " samples, " << J["samples_used"] << " used), system <b>" << esc(J["system"])
    << "</b>.</p>\n";
  h << "<p>Method: " << esc(J["method"]["domain"].get<std::string>()) << "; "
    << esc(J["method"]["filter"].get<std::string>()) << "; decimation " << J["method"]["decimation"]
    << "; " << esc(J["method"]["selection"].get<std::string>()) << "; "
    << esc(J["method"]["moving_only"].get<std::string>()) << ". Noise floor of the force: "
    << num(J["noise_floor_n"].get<double>()) << " N.</p>\n";
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
  for (const auto& w : r.where) h << "<li>" << esc(w) << "</li>";
  if (r.where.empty()) h << "<li>no region stands out</li>";
  h << "</ul><p>Events:</p><ul>";
  for (const auto& e : J["events"]) h << "<li>" << esc(e.dump()) << "</li>";
  if (J["events"].empty()) h << "<li>none</li>";
  h << "</ul>\n<h2>3. Explain</h2><p><b>" << esc(J["conclusion"].get<std::string>()) << "</b></p>";
  h << "<table><tr><th>#</th><th>effect</th><th>parameters</th><th>where</th><th>held-out gain</th>"
       "<th>t</th><th>segments</th><th>improvement</th></tr>";
  int k = 1;
  for (const auto& e : J["effects"]) {
    const auto& ev = e["evidence"];
    h << "<tr><td>" << k++ << "</td><td><b>" << esc(e["id"]) << "</b>";
    if (e.contains("finding"))
      h << "<div class=alt>" << esc(e["finding"].get<std::string>()) << "</div>";
    if (e.contains("alternatives"))
      for (const auto& a : e["alternatives"])
        h << "<div class=alt>alternative: " << esc(a["id"]) << " (" << esc(params_text(a["parameters"]))
          << "; reproduces " << num(a["explains_pct"].get<double>(), 3) << " %)</div>";
    if (e.contains("note")) h << "<div>" << esc(e["note"].get<std::string>()) << "</div>";
    h << "</td><td>" << esc(params_text(e["parameters"])) << "</td><td>" << esc(e["where"])
      << "</td><td>"
      << (ev["heldout_gain_pct"].is_number() ? num(ev["heldout_gain_pct"].get<double>(), 3) + " %" : "–")
      << "</td><td>" << (ev.contains("t_stat") ? num(ev["t_stat"].get<double>(), 3) : "–") << "</td><td>"
      << (ev.contains("segments_improved") ? ev["segments_improved"].get<std::string>() : "–")
      << "</td><td>" << num(e["improvement_pct"].get<double>(), 3) << " %</td></tr>";
  }
  h << "</table>";
  for (const auto& rj : J["not_selected"])
    h << "<p>Next best candidate, not significant: " << esc(rj["id"]) << " (held-out gain "
      << num(rj["heldout_gain_pct"].get<double>(), 3) << " %, t = " << num(rj["t_stat"].get<double>(), 3)
      << ")</p>";
  h << "<h2>4. Model it</h2><table><tr><th>model</th><th>held-out RMS [N]</th><th>held-out relative error [%]</th></tr>";
  for (const auto& v : J["validation"])
    h << "<tr><td>" << esc(v["model"]) << "</td><td>" << num(v["heldout_rms"].get<double>()) << "</td><td>"
      << num(v["heldout_relative_error_pct"].get<double>()) << "</td></tr>";
  h << "</table><p>Corrected model written to <code>model_corrected.toml</code>.</p>";
  if (J.contains("twin_simulation"))
    h << "<p>Twin re-simulation: " << esc(J["twin_simulation"].dump()) << "</p>";
  h << "<h2>Figures</h2>";
  for (const auto& f : r.figures)
    h << "<figure><img src=\"data:image/png;base64," << base64_file(path(f.file)) << "\" alt=\""
      << esc(f.file) << "\"><figcaption>" << esc(f.caption) << "</figcaption></figure>\n";
  h << "</body></html>\n";
  std::ofstream out(path("report.html"));
  out << h.str();
  if (!out) throw std::runtime_error("cannot write " + path("report.html"));
}

}  // namespace maglead::analysis
