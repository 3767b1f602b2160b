#pragma once
// Reading TOML configuration files with errors that point at FILE:LINE:COLUMN: toml++ keeps the
// source region of every node. Included by the .cpp files that read config files (they link
// toml++ themselves); each error names the key and what was expected.
#include <filesystem>
#include <stdexcept>
#include <string>
#include <toml++/toml.h>

namespace maglead::config {

/// "FILE:LINE:COLUMN" of a source region (FILE:1:1 when it has none).
inline std::string where(const std::string& path, const toml::source_region& r) {
  const auto line = r.begin.line ? r.begin.line : 1u;
  const auto column = r.begin.column ? r.begin.column : 1u;
  return path + ":" + std::to_string(line) + ":" + std::to_string(column);
}

/// Throws std::runtime_error "FILE:LINE:COLUMN: what" at the node (FILE:1:1 without one).
[[noreturn]] inline void fail(const std::string& path, const toml::node* node, const std::string& what) {
  throw std::runtime_error((node ? where(path, node->source()) : path + ":1:1") + ": " + what);
}

/// Parses a file; a syntax error names FILE:LINE:COLUMN and what toml++ found wrong.
inline toml::table parse_file(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw std::runtime_error(path + ": no such file");
  try {
    return toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    throw std::runtime_error(where(path, e.source()) + ": " + std::string(e.description()));
  }
}

}  // namespace maglead::config
