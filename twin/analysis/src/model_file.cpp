#include "maglead/analysis/model_file.hpp"

#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <toml++/toml.h>

namespace maglead::analysis {

double ModelTerm::get(const std::string& key, double fallback) const {
  for (const auto& [k, v] : parameters)
    if (k == key) return v;
  return fallback;
}

void ModelTerm::set(const std::string& key, double value) {
  for (auto& [k, v] : parameters)
    if (k == key) {
      v = value;
      return;
    }
  parameters.emplace_back(key, value);
}

const ModelTerm* ModelFile::find(const std::string& id) const {
  for (const auto& t : terms)
    if (t.id == id && t.enabled) return &t;
  return nullptr;
}

ModelTerm& ModelFile::term(const std::string& id) {
  for (auto& t : terms)
    if (t.id == id) return t;
  terms.push_back({id, true, "", {}});
  return terms.back();
}

ModelFile load_model(const std::string& path) {
  toml::table doc;
  try {
    doc = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    std::ostringstream m;
    m << path << ":" << e.source().begin.line << ":" << e.source().begin.column << ": "
      << e.description();
    throw std::runtime_error(m.str());
  }
  ModelFile model;
  auto* mt = doc["model"].as_table();
  if (!mt) throw std::runtime_error(path + ": missing [model] table");
  for (const auto& [k, v] : *mt) {
    const std::string key(k.str());
    if (key == "system" || key == "source") {
      auto s = v.value<std::string>();
      if (!s) throw std::runtime_error(path + ": [model] " + key + " must be a string");
      (key == "system" ? model.system : model.source) = *s;
    } else if (key == "nut_mass_kg" || key == "viscous_n_s_per_m" || key == "coulomb_n") {
      auto d = v.value<double>();
      if (!d) throw std::runtime_error(path + ": [model] " + key + " is not a number");
      (key == "nut_mass_kg" ? model.nut_mass_kg
                            : key == "viscous_n_s_per_m" ? model.viscous_n_s_per_m : model.coulomb_n) = *d;
    } else if (key == "fit") {
      auto* arr = v.as_array();
      if (!arr) throw std::runtime_error(path + ": [model] fit must be a list of key names");
      for (const auto& e : *arr) {
        auto s = e.value<std::string>();
        if (!s || (*s != "nut_mass_kg" && *s != "viscous_n_s_per_m" && *s != "coulomb_n"))
          throw std::runtime_error(path + ": [model] fit: entries must be \"nut_mass_kg\", "
                                          "\"viscous_n_s_per_m\" or \"coulomb_n\"");
        model.fit.insert(*s);
      }
    } else {
      throw std::runtime_error(path + ": [model] unknown key '" + key + "'");
    }
  }
  if (model.system != "actuator" && model.system != "axis")
    throw std::runtime_error(path + ": [model] system = '" + model.system +
                             "' (expected \"actuator\" or \"axis\")");
  if (auto* terms = doc["term"].as_array()) {
    for (std::size_t i = 0; i < terms->size(); ++i) {
      auto* t = (*terms)[i].as_table();
      const std::string where = path + ": term " + std::to_string(i + 1);
      if (!t) throw std::runtime_error(where + " is not a table");
      ModelTerm term;
      auto id = (*t)["id"].value<std::string>();
      if (!id) throw std::runtime_error(where + " has no id");
      term.id = *id;
      for (const auto& [k, v] : *t) {
        const std::string key(k.str());
        if (key == "id") continue;
        if (key == "enabled") {
          if (!v.is_boolean()) throw std::runtime_error(where + ": enabled must be true or false");
          term.enabled = *v.value<bool>();
        } else if (key == "note") {
          term.note = v.value_or(std::string());
        } else if (auto d = v.value<double>()) {
          term.parameters.emplace_back(key, *d);
        } else {
          throw std::runtime_error(where + " ('" + term.id + "'): '" + key + "' is not a number");
        }
      }
      model.terms.push_back(std::move(term));
    }
  }
  return model;
}

namespace {
std::string quoted(const std::string& s) {
  std::string o = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') o += '\\';
    o += c == '\n' ? ' ' : c;
  }
  return o + "\"";
}
}  // namespace

void save_model(const std::string& path, const ModelFile& model, const std::string& header) {
  std::ofstream f(path);
  if (!f) throw std::runtime_error("cannot write " + path);
  std::istringstream lines(header);
  for (std::string line; std::getline(lines, line);) f << "# " << line << "\n";
  f << std::setprecision(10) << "[model]\n";
  if (model.system != "actuator") f << "system = " << quoted(model.system) << "\n";
  f << "source = " << quoted(model.source) << "\n"
    << "nut_mass_kg = " << model.nut_mass_kg << "\n"
    << "viscous_n_s_per_m = " << model.viscous_n_s_per_m << "\n"
    << "coulomb_n = " << model.coulomb_n << "\n";
  if (!model.fit.empty()) {
    f << "fit = [";
    bool first = true;
    for (const auto& k : model.fit) f << (first ? "" : ", ") << quoted(k), first = false;
    f << "]\n";
  }
  for (const auto& t : model.terms) {
    f << "\n[[term]]\nid = " << quoted(t.id) << "\n";
    if (!t.enabled) f << "enabled = false\n";
    if (!t.note.empty()) f << "note = " << quoted(t.note) << "\n";
    for (const auto& [k, v] : t.parameters) f << k << " = " << v << "\n";
  }
  if (!f) throw std::runtime_error("cannot write " + path);
}

}  // namespace maglead::analysis
