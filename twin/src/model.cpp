#include "maglead/twin/model.hpp"

#include "maglead/fileio/atomic_file.hpp"
#include "maglead/physics/toml_config.hpp"

#include "maglead/effects/axis_kind.hpp"
#include "maglead/effects/effect.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace maglead::twin {

double ModelTerm::get(const std::string& name, double fallback) const {
  for (const auto& [k, v] : parameters)
    if (k == name) return v;
  return fallback;
}

void ModelTerm::set(const std::string& name, double value) {
  for (auto& [k, v] : parameters)
    if (k == name) {
      v = value;
      return;
    }
  parameters.emplace_back(name, value);
}

const ModelTerm* TwinModel::find(const std::string& id) const {
  for (const auto& t : terms)
    if (t.id == id && t.enabled) return &t;
  return nullptr;
}

ModelTerm& TwinModel::term(const std::string& id) {
  for (auto& t : terms)
    if (t.id == id) return t;
  terms.push_back({id, true, "", {}});
  return terms.back();
}

void validate_twin_model(const TwinModel& m) {
  if (m.system != "actuator" && !effects::axis_kind_of_system(m.system))
    throw std::invalid_argument("[model] system = '" + m.system +
                                "' (expected \"actuator\", \"axis\" or \"rotary\")");
  // The messages name the values as the file does (a rotary model's inertia_kg_m2, …).
  const effects::AxisKind* kind = effects::axis_kind_of_system(m.system);
  const auto file_name = [&](const char* n) { return kind ? kind->name_of(n) : std::string(n); };
  const std::string mass = file_name("nut_mass_kg"), viscous = file_name("viscous_n_s_per_m"),
                    coulomb = file_name("coulomb_n");
  if (!(m.nut_mass_kg >= 0.0) || !std::isfinite(m.nut_mass_kg) ||
      (m.system == "actuator" && !(m.nut_mass_kg > 0.0)))
    throw std::invalid_argument(mass + " must be positive");
  if (!(m.viscous_n_s_per_m >= 0.0) || !(m.coulomb_n >= 0.0))
    throw std::invalid_argument(viscous + " and " + coulomb + " must be >= 0");
  for (const auto& k : m.fit)
    if (k != "nut_mass_kg" && k != "viscous_n_s_per_m" && k != "coulomb_n")
      throw std::invalid_argument("[model] fit: '" + k + "' (expected " + mass + ", " + viscous +
                                  " or " + coulomb + ")");
  for (std::size_t i = 0; i < m.terms.size(); ++i) {
    const auto& t = m.terms[i];
    const auto* e = effects::find(t.id);
    if (!e) {
      std::string known;
      for (const auto* k : effects::library())
        known += (known.empty() ? "" : ", ") + std::string(k->id());
      throw std::invalid_argument("term " + std::to_string(i + 1) + ": unknown id '" + t.id +
                                  "' (known: " + known + ")");
    }
    try {
      effects::check(*e, effects::Params(t.parameters.begin(), t.parameters.end()));
    } catch (const std::invalid_argument& err) {
      std::string allowed;
      for (const auto& p : e->params()) allowed += (allowed.empty() ? "" : ", ") + p.name;
      throw std::invalid_argument("term " + std::to_string(i + 1) + ": " + err.what() +
                                  " (parameters: " + allowed + ")");
    }
  }
}

namespace {

// The file's names of the units' parameters: a rotary axis's carry its units
// (`inertia_kg_m2` for `nut_mass_kg`, effects/axis_kind.hpp); every other system's are the units'.
const effects::AxisKind& kind_of(const std::string& system) {
  const effects::AxisKind* k = effects::axis_kind_of_system(system);
  return k ? *k : effects::linear_axis();
}

bool has_parameter(const effects::Effect& e, const std::string& key) {
  for (const auto& p : e.params())
    if (p.name == key) return true;
  return false;
}

std::string parameter_list(const effects::Effect& e, const effects::AxisKind& kind) {
  std::string out;
  for (const auto& p : e.params()) out += (out.empty() ? "" : ", ") + kind.name_of(p.name);
  return out;
}

// One [[term]] of the file, its parameter names read in the kind's (`where`: "[[term]] N").
ModelTerm read_term(const std::string& path, const toml::node& node, const std::string& where,
                    const effects::AxisKind& kind) {
  const toml::table* t = node.as_table();
  if (!t) config::fail(path, &node, where + " is not a table");
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
      const std::string name = kind.name == "linear" ? key : kind.unit_name_of(key);
      if (const auto* e = effects::find(term.id); e && (name.empty() || !has_parameter(*e, name)))
        config::fail(path, &value,
                     where + " (" + term.id + ") has no parameter '" + key +
                         "' (parameters: " + parameter_list(*e, kind) + ")");
      const auto v = value.value<double>();
      if (!v) config::fail(path, &value, where + " (" + term.id + ") " + key + " is not a number");
      term.parameters.emplace_back(name.empty() ? key : name, *v);
    }
  }
  return term;
}

}  // namespace

void check_model_format(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot open (" + std::strerror(errno) + ")");
  std::string first;
  std::getline(f, first);
  while (!first.empty() && (first.back() == '\r' || first.back() == ' ')) first.pop_back();
  if (first.rfind("# format:", 0) != 0)
    throw std::runtime_error(path + ":1:1: a model file starts with the line '" +
                             std::string(kModelFormatLine) +
                             "' (add it; without it another TOML file could be taken for a model)");
  if (first != kModelFormatLine) {
    // "# format:" with nothing after it names no format (found by tests/fuzz/fuzz_config).
    const std::size_t name_at = first.find_first_not_of(' ', 9);
    throw std::runtime_error(path + ":1:11: format '" +
                             (name_at == std::string::npos ? "" : first.substr(name_at)) +
                             "' is not maglead-model/1");
  }
}

TwinModel load_twin_model(const std::string& path) {
  check_model_format(path);
  const toml::table root = config::parse_file(path);
  const toml::table* mt = config::section(path, root, "model", true);
  TwinModel m;
  m.source = (*mt)["source"].value_or(std::string(path));
  m.system = (*mt)["system"].value_or(std::string("actuator"));
  const effects::AxisKind& kind = kind_of(m.system);
  const std::string mass = kind.name_of("nut_mass_kg"), viscous = kind.name_of("viscous_n_s_per_m"),
                    coulomb = kind.name_of("coulomb_n");
  if (const toml::node* f = mt->get("fit")) {
    const toml::array* arr = f->as_array();
    if (!arr) config::fail(path, f, "[model] fit must be a list of key names");
    for (const auto& e : *arr) {
      const std::string key = e.value_or(std::string("?"));
      const std::string name = kind.name == "linear" ? key : kind.unit_name_of(key);
      m.fit.insert(name.empty() ? key : name);
    }
  }
  config::read_number(path, *mt, "[model]", mass.c_str(), m.nut_mass_kg);
  config::read_number(path, *mt, "[model]", viscous.c_str(), m.viscous_n_s_per_m);
  config::read_number(path, *mt, "[model]", coulomb.c_str(), m.coulomb_n);
  config::check_keys(path, *mt, "[model]", {"source", "system", "fit", mass, viscous, coulomb});
  std::vector<const toml::node*> term_nodes;  // for errors found by validation
  if (const toml::node* terms = root.get("term")) {
    const toml::array* arr = terms->as_array();
    if (!arr) config::fail(path, terms, "'term' must be an array of tables ([[term]])");
    for (std::size_t i = 0; i < arr->size(); ++i) {
      term_nodes.push_back(&(*arr)[i]);
      m.terms.push_back(read_term(path, (*arr)[i], "[[term]] " + std::to_string(i + 1), kind));
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

namespace {
// The shortest text that reads back as the same double (0.0025, never 0.0025000000000000001).
// A large whole number would be written as digits alone (85555555555555557376), which TOML reads
// as an integer beyond 64 bits: from 1e15 on (past what a TOML integer holds exactly) it is
// written with an exponent, a float to any reader.
std::string shortest(double v) {
  constexpr double kDigitsAloneBelow = 1e15;
  char b[32];
  const auto r = std::abs(v) < kDigitsAloneBelow
                     ? std::to_chars(b, b + sizeof b, v)
                     : std::to_chars(b, b + sizeof b, v, std::chars_format::scientific);
  return std::string(b, r.ptr);
}
}  // namespace

void save_twin_model(const std::string& path, const TwinModel& m,
                     const std::string& header_comment) {
  validate_twin_model(m);
  std::ostringstream out;  // then written atomically: `serve --model` never sees half a model
  const auto quoted = [](const std::string& s) {
    std::string q = "\"";
    for (char c : s) {
      if (c == '"' || c == '\\') q += '\\';
      if (c == '\n') {
        q += "\\n";
        continue;
      }
      // TOML forbids control characters other than tab inside a string: a note or source read
      // from a file as "\u0001" must be written back escaped, or the file cannot be read again
      // (found by tests/fuzz/fuzz_config).
      const auto u = static_cast<unsigned char>(c);
      if ((u < 0x20 && c != '\t') || u == 0x7F) {
        char esc[8];
        std::snprintf(esc, sizeof esc, "\\u%04X", u);
        q += esc;
        continue;
      }
      q += c;
    }
    return q + "\"";
  };
  out << kModelFormatLine
      << "\n# maglead model file (format: twin/include/maglead/twin/model.hpp)\n";
  std::string line;
  for (std::istringstream lines(header_comment); std::getline(lines, line);)
    out << "# " << line << "\n";
  out << "[model]\n";
  if (m.system != "actuator") out << "system = " << quoted(m.system) << "\n";
  const effects::AxisKind& kind = kind_of(m.system);
  out << "source = " << quoted(m.source) << "\n"
      << kind.name_of("nut_mass_kg") << " = " << shortest(m.nut_mass_kg) << "\n"
      << kind.name_of("viscous_n_s_per_m") << " = " << shortest(m.viscous_n_s_per_m) << "\n"
      << kind.name_of("coulomb_n") << " = " << shortest(m.coulomb_n) << "\n";
  if (!m.fit.empty()) {
    out << "fit = [";
    bool first = true;
    for (const auto& k : m.fit)
      out << (first ? "" : ", ") << quoted(kind.name_of(k)), first = false;
    out << "]\n";
  }
  for (const auto& t : m.terms) {
    out << "\n[[term]]\nid = " << quoted(t.id) << "\n";
    if (!t.enabled) out << "enabled = false\n";
    if (!t.note.empty()) out << "note = " << quoted(t.note) << "\n";
    for (const auto& [k, v] : t.parameters) {
      // A whole number prints bare ("2"), which toml++ still reads as a number.
      out << kind.name_of(k) << " = " << shortest(v) << "\n";
    }
  }
  write_file_atomically(path, out.str());
}

FrictionModel friction_model(const TwinModel& model) {
  FrictionModel f;
  double fc = model.coulomb_n, c = model.viscous_n_s_per_m;
  if (const auto* t = model.find("coulomb_friction")) fc = t->get("coulomb_n", fc);
  if (const auto* t = model.find("viscous_friction")) c = t->get("viscous_n_s_per_m", c);
  double fc_pos = fc, fc_neg = fc, c_pos = c, c_neg = c;
  if (const auto* t = model.find("asymmetric_friction")) {
    fc_pos = t->get("coulomb_pos_n", fc);
    fc_neg = t->get("coulomb_neg_n", fc);
    c_pos = t->get("viscous_pos_n_s_per_m", c);
    c_neg = t->get("viscous_neg_n_s_per_m", c);
  }
  double excess = 0.0;  // Stribeck: break-away above the kinetic level, both directions
  if (const auto* t = model.find("stribeck_friction")) {
    const double kinetic = t->get("coulomb_n", fc);
    fc_pos += kinetic - fc;
    fc_neg += kinetic - fc;
    excess = std::max(0.0, t->get("breakaway_n", kinetic) - kinetic);
    f.stribeck_velocity_m_s = t->get("stribeck_velocity_m_s", 0.0);
  }
  f.coulomb_pos_n = fc_pos, f.coulomb_neg_n = fc_neg;
  f.breakaway_pos_n = fc_pos + excess, f.breakaway_neg_n = fc_neg + excess;
  f.viscous_pos_n_s_per_m = c_pos, f.viscous_neg_n_s_per_m = c_neg;
  if (const auto* t = model.find("offset")) f.offset_n = t->get("offset_n", 0.0);
  f.nut_mass_kg = model.nut_mass_kg;
  if (const auto* t = model.find("mass_error"))
    f.nut_mass_kg = t->get("nut_mass_kg", f.nut_mass_kg);
  return f;
}

CouplingModel coupling_model(const TwinModel& model) {
  CouplingModel c;
  if (const auto* t = model.find("coupling_gain_error")) c.gain = t->get("gain", 1.0);
  if (const auto* t = model.find("angle_ripple")) {
    c.angle_ripple = t->get("relative_amplitude", 0.0);
    c.angle_ripple_phase_rad = t->get("phase_rad", 0.0);
  }
  if (const auto* t = model.find("end_effect")) {
    c.end_zone_m = t->get("zone_m", 0.0);
    c.end_max_reduction = t->get("max_reduction", 0.0);
  }
  return c;
}

}  // namespace maglead::twin
