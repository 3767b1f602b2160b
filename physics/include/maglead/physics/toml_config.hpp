#pragma once
// Reading TOML configuration files with errors that point at FILE:LINE:COLUMN: toml++ keeps the
// source region of every node. The one reader of the project's TOML files (configuration, model
// files, calibrations): parse, find a section, refuse unknown keys, read numbers. Included by the
// .cpp files that read them (they link toml++ themselves); each error names the key and what was
// expected.
#include <toml++/toml.h>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace maglead::config {

/// "FILE:LINE:COLUMN" of a source region (FILE:1:1 when it has none).
inline std::string where(const std::string& path, const toml::source_region& r) {
  const auto line = r.begin.line ? r.begin.line : 1u;
  const auto column = r.begin.column ? r.begin.column : 1u;
  return path + ":" + std::to_string(line) + ":" + std::to_string(column);
}

/// Throws std::runtime_error "FILE:LINE:COLUMN: what" at the node (FILE:1:1 without one).
[[noreturn]] inline void fail(const std::string& path, const toml::node* node,
                              const std::string& what) {
  throw std::runtime_error((node ? where(path, node->source()) : path + ":1:1") + ": " + what);
}

/// A number written with a unit ("stroke_max_m = 40mm") is a syntax error to TOML; say which key
/// and that the name's ending is the unit (empty for other errors).
inline std::string unit_hint(const std::string& path, const toml::parse_error& e) {
  if (std::string(e.description()).find("digit") == std::string::npos) return {};
  std::ifstream f(path);
  std::string line;
  for (auto n = e.source().begin.line; n > 0 && std::getline(f, line);) --n;
  const auto eq = line.find('=');
  if (eq == std::string::npos) return {};
  std::string key = line.substr(0, eq);
  key.erase(key.find_last_not_of(" \t") + 1);
  key.erase(0, key.find_first_not_of(" \t"));
  return " (key '" + key +
         "': a number is written without a unit, in the SI unit its name ends with, e.g. _m: "
         "metres, _n: newtons)";
}

/// Parses a file; a syntax error names FILE:LINE:COLUMN and what toml++ found wrong.
inline toml::table parse_file(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw std::runtime_error(path + ": no such file");
  try {
    return toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    throw std::runtime_error(where(path, e.source()) + ": " + std::string(e.description()) +
                             unit_hint(path, e));
  }
}

/// The table `name` of `root`, or nullptr when there is none (`required`: an error then). A key
/// `name` that is not a table is an error at it.
inline const toml::table* section(const std::string& path, const toml::table& root,
                                  const std::string& name, bool required = false) {
  const toml::node* node = root.get(name);
  if (!node) {
    if (!required) return nullptr;
    std::string has;  // what the file holds instead: a misspelt [modle] is then plain to see
    for (const auto& [k, v] : root) has += (has.empty() ? "" : ", ") + std::string(k.str());
    fail(path, nullptr,
         "missing [" + name + "] table (" +
             (has.empty() ? std::string("the file is empty") : "the file has: " + has) + ")");
  }
  const toml::table* t = node->as_table();
  if (!t) fail(path, node, "[" + name + "] must be a table");
  return t;
}

/// Fails at the first key of `t` not in `known`: "LABEL unknown key 'k' (known: a, b, …)".
inline void check_keys(const std::string& path, const toml::table& t, const std::string& label,
                       std::initializer_list<std::string_view> known) {
  for (const auto& [k, v] : t) {
    bool ok = false;
    for (const auto name : known) ok = ok || k.str() == name;
    if (ok) continue;
    std::string list;
    for (const auto name : known) list += (list.empty() ? "" : ", ") + std::string(name);
    fail(path, &v, label + " unknown key '" + std::string(k.str()) + "' (known: " + list + ")");
  }
}

/// Reads t[key] into `out` when it is there (returns whether it was). A value that is not a
/// number, or that `ok` refuses, is an error at the value: "LABEL key must be EXPECTED".
template <class Ok>
bool read_number(const std::string& path, const toml::table& t, const std::string& label,
                 const char* key, double& out, Ok ok, const std::string& expected) {
  const toml::node* node = t.get(key);
  if (!node) return false;
  const auto v = node->value<double>();
  if (!v || !ok(*v)) fail(path, node, label + " " + key + " must be " + expected);
  out = *v;
  return true;
}

/// Any finite number.
inline bool read_number(const std::string& path, const toml::table& t, const std::string& label,
                        const char* key, double& out) {
  return read_number(
      path, t, label, key, out, [](double v) { return std::isfinite(v); }, "a number");
}

/// The array t[key] of finite numbers (required): "LABEL key missing or not an array", "LABEL key
/// holds a non-numeric value" at the offending node.
inline std::vector<double> read_numbers(const std::string& path, const toml::table& t,
                                        const std::string& label, const char* key) {
  const toml::array* arr = t[key].as_array();
  if (!arr)
    fail(path, t.get(key) ? t.get(key) : static_cast<const toml::node*>(&t),
         label + " " + key + " missing or not an array");
  std::vector<double> out;
  for (const auto& el : *arr) {
    const auto v = el.value<double>();
    if (!v || !std::isfinite(*v)) fail(path, &el, label + " " + key + " holds a non-numeric value");
    out.push_back(*v);
  }
  return out;
}

}  // namespace maglead::config
