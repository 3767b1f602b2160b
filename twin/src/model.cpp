#include "maglead/twin/model.hpp"

#include "maglead/physics/toml_config.hpp"

#include <algorithm>
#include <cstdlib>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <stdexcept>

namespace maglead::twin {

double ModelTerm::get(const std::string& name, double fallback) const {
  for (const auto& [k, v] : parameters)
    if (k == name) return v;
  return fallback;
}

const std::vector<TermInfo>& known_terms() {
  static const std::vector<TermInfo> terms = {
      {"coulomb_friction", {"n"}, "extra Coulomb friction level [N], adds to coulomb_n", true},
      {"viscous_friction", {"n_s_per_m"}, "extra viscous friction [N s/m], adds to C", true},
      {"asymmetric_friction", {"n"}, "Coulomb + n moving +p, - n moving -p [N]", true},
      {"stribeck_friction", {"n", "velocity_m_s"}, "break-away excess n exp(-(v/v_s)^2)", true},
      {"offset", {"force_n"}, "constant force on the nut along +p [N]", true},
      {"spring", {"n_per_m", "center_m"}, "force -k (p - center) [N/m, m]", true},
      {"mass_error", {"kg"}, "extra moving mass [kg]", true},
      {"gain", {"factor"}, "coupling strength factor (1 = as calibrated)", true},
      {"gain_drift", {"per_min"}, "coupling strength x (1 + per_min t / 60 s)", true},
      {"angle_ripple", {"n", "phase_rad"}, "n sin(theta + phase), once per screw turn", true},
      {"position_ripple", {"n", "period_m", "phase_rad"}, "n sin(2 pi p / period + phase)", true},
      {"end_effect", {"m", "depth"}, "coupling weakens within m of a stroke end", true},
      {"step_out", {}, "always modelled (periodic coupling)", true},
      {"backlash", {"rad"}, "gear play at the screw (not simulated by the twin)", false},
      {"sensor_delay", {"s"}, "linear-encoder delay (not simulated by the twin)", false},
      {"external_disturbance", {"n", "t_s", "duration_s"},
       "isolated force pulses (not simulated by the twin)", false},
  };
  return terms;
}

std::vector<std::string> TwinModel::unsimulated_terms() const {
  std::vector<std::string> out;
  for (const auto& t : terms) {
    if (!t.enabled) continue;
    for (const auto& k : known_terms())
      if (k.id == t.id && !k.simulated) out.push_back(t.id);
  }
  return out;
}

void validate_twin_model(const TwinModel& m) {
  if (!(m.nut_mass_kg > 0.0) || !std::isfinite(m.nut_mass_kg))
    throw std::invalid_argument("nut_mass_kg must be positive");
  if (!(m.viscous_n_s_per_m >= 0.0) || !(m.coulomb_n >= 0.0))
    throw std::invalid_argument("viscous_n_s_per_m and coulomb_n must be >= 0");
  for (std::size_t i = 0; i < m.terms.size(); ++i) {
    const auto& t = m.terms[i];
    const auto it = std::find_if(known_terms().begin(), known_terms().end(),
                                 [&](const TermInfo& k) { return k.id == t.id; });
    if (it == known_terms().end()) {
      std::string known;
      for (const auto& k : known_terms()) known += (known.empty() ? "" : ", ") + k.id;
      throw std::invalid_argument("term " + std::to_string(i + 1) + ": unknown id '" + t.id +
                                  "' (known: " + known + ")");
    }
    for (const auto& [name, value] : t.parameters) {
      if (std::find(it->parameters.begin(), it->parameters.end(), name) == it->parameters.end()) {
        std::string allowed;
        for (const auto& p : it->parameters) allowed += (allowed.empty() ? "" : ", ") + p;
        throw std::invalid_argument("term " + std::to_string(i + 1) + " (" + t.id +
                                    "): unknown parameter '" + name + "' (allowed: " +
                                    (allowed.empty() ? "none" : allowed) + ")");
      }
      if (!std::isfinite(value))
        throw std::invalid_argument("term " + std::to_string(i + 1) + " (" + t.id + "): " + name +
                                    " is not finite");
    }
  }
}

void check_model_format(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot open");
  std::string first;
  std::getline(f, first);
  while (!first.empty() && (first.back() == '\r' || first.back() == ' ')) first.pop_back();
  if (first.rfind("# format:", 0) != 0)
    throw std::runtime_error(path + ":1:1: a model file starts with the line '" + std::string(kModelFormatLine) +
                             "' (add it; without it another TOML file could be taken for a model)");
  if (first != kModelFormatLine)
    throw std::runtime_error(path + ":1:11: format '" + first.substr(first.find_first_not_of(' ', 9)) +
                             "' is not maglead-model/1");
}

TwinModel load_twin_model(const std::string& path) {
  check_model_format(path);
  const toml::table root = config::parse_file(path);
  const toml::table* mt = root["model"].as_table();
  if (!mt) config::fail(path, root.get("model"), "missing [model] table");
  TwinModel m;
  const auto num = [&](const toml::table& t, const char* key, double& out, const std::string& where) {
    const toml::node* n = t.get(key);
    if (!n) return;
    const auto v = n->value<double>();
    if (!v) config::fail(path, n, where + " " + key + " is not a number");
    out = *v;
  };
  m.source = (*mt)["source"].value_or(std::string(path));
  num(*mt, "nut_mass_kg", m.nut_mass_kg, "[model]");
  num(*mt, "viscous_n_s_per_m", m.viscous_n_s_per_m, "[model]");
  num(*mt, "coulomb_n", m.coulomb_n, "[model]");
  for (const auto& [k, v] : *mt) {
    const std::string key(k.str());
    if (key != "source" && key != "nut_mass_kg" && key != "viscous_n_s_per_m" && key != "coulomb_n")
      config::fail(path, &v, "[model] unknown key '" + key + "'");
  }
  std::vector<const toml::node*> term_nodes;  // for errors found by validation
  if (const toml::node* terms = root.get("term")) {
    const toml::array* arr = terms->as_array();
    if (!arr) config::fail(path, terms, "'term' must be an array of tables ([[term]])");
    for (std::size_t i = 0; i < arr->size(); ++i) {
      const toml::node& node = (*arr)[i];
      const toml::table* t = node.as_table();
      const std::string where = "[[term]] " + std::to_string(i + 1);
      if (!t) config::fail(path, &node, where + " is not a table");
      term_nodes.push_back(&node);
      ModelTerm term;
      const auto id = (*t)["id"].value<std::string>();
      if (!id) config::fail(path, t->get("id") ? t->get("id") : &node, where + " has no id (a string)");
      term.id = *id;
      for (const auto& [k, value] : *t) {
        const std::string key(k.str());
        if (key == "id") continue;
        if (key == "enabled") {
          const auto b = value.value<bool>();
          if (!b) config::fail(path, &value, where + " enabled must be true or false");
          term.enabled = *b;
        } else if (key == "note") {
          term.note = value.value_or(std::string());
        } else {
          const auto v = value.value<double>();
          if (!v) config::fail(path, &value, where + " (" + term.id + ") " + key + " is not a number");
          term.parameters.emplace_back(key, *v);
        }
      }
      m.terms.push_back(std::move(term));
    }
  }
  try {
    validate_twin_model(m);
  } catch (const std::invalid_argument& e) {
    // "term N ..." points at that [[term]]; anything else at [model].
    const std::string what = e.what();
    const toml::node* at = root.get("model");
    if (what.rfind("term ", 0) == 0) {
      const auto n = static_cast<std::size_t>(std::atoi(what.c_str() + 5));
      if (n >= 1 && n <= term_nodes.size()) at = term_nodes[n - 1];
    }
    config::fail(path, at, what);
  }
  return m;
}

void save_twin_model(const std::string& path, const TwinModel& m, const std::string& header_comment) {
  validate_twin_model(m);
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot write");
  const auto quoted = [](const std::string& s) {
    std::string q = "\"";
    for (char c : s) {
      if (c == '"' || c == '\\') q += '\\';
      if (c == '\n') { q += "\\n"; continue; }
      q += c;
    }
    return q + "\"";
  };
  out << kModelFormatLine << "\n# maglead twin model (format: twin/include/maglead/twin/model.hpp)\n";
  if (!header_comment.empty()) out << "# " << header_comment << "\n";
  out << std::setprecision(12) << "[model]\n"
      << "source = " << quoted(m.source) << "\n"
      << "nut_mass_kg = " << m.nut_mass_kg << "\n"
      << "viscous_n_s_per_m = " << m.viscous_n_s_per_m << "\n"
      << "coulomb_n = " << m.coulomb_n << "\n";
  for (const auto& t : m.terms) {
    out << "\n[[term]]\nid = " << quoted(t.id) << "\n";
    if (!t.enabled) out << "enabled = false\n";
    if (!t.note.empty()) out << "note = " << quoted(t.note) << "\n";
    for (const auto& [k, v] : t.parameters) {
      // TOML floats need a dot or exponent to stay floats on re-read; setprecision prints
      // integers bare, which toml++ still reads as a number (value<double> converts).
      out << k << " = " << v << "\n";
    }
  }
  if (!out) throw std::runtime_error(path + ": write failed");
}

}  // namespace maglead::twin
