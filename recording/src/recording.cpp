#include "maglead/recording/recording.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

namespace maglead {

bool Recording::has(const std::string& name) const {
  for (const auto& n : names)
    if (n == name) return true;
  return false;
}

const std::vector<double>& Recording::column(const std::string& name) const {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return columns[i];
  throw RecordingError(path + ": no column '" + name + "'");
}

std::vector<double>& Recording::add_column(const std::string& name, std::vector<double> values) {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return columns[i] = std::move(values);
  names.push_back(name);
  columns.push_back(std::move(values));
  return columns.back();
}

std::optional<std::string> Recording::meta(const std::string& key) const {
  for (const auto& [k, v] : metadata)
    if (k == key) return v;
  return std::nullopt;
}

void Recording::set_meta(const std::string& key, const std::string& value) {
  for (auto& [k, v] : metadata)
    if (k == key) {
      v = value;
      return;
    }
  metadata.emplace_back(key, value);
}

namespace {

std::string trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return std::string(s);
}

std::string where(const std::string& path, std::size_t line) {
  return path + ":" + std::to_string(line) + ": ";
}

}  // namespace

Recording read_recording(const std::string& path, const std::vector<std::string>& required) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw RecordingError(path + ": cannot open");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  Recording rec;
  rec.path = path;

  std::size_t pos = 0, line_no = 0;
  auto next_line = [&](std::string_view& line) {
    if (pos >= text.size()) return false;
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    line = std::string_view(text).substr(pos, end - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos = end + 1;
    ++line_no;
    return true;
  };

  std::string_view line;
  bool have_header = false;
  while (next_line(line)) {
    if (line.empty()) continue;
    if (line.front() == '#') {
      std::string_view body = line.substr(1);
      const std::size_t colon = body.find(':');
      if (colon != std::string_view::npos)
        rec.metadata.emplace_back(trim(body.substr(0, colon)), trim(body.substr(colon + 1)));
      continue;
    }
    std::size_t start = 0;
    while (true) {
      const std::size_t comma = line.find(',', start);
      rec.names.push_back(trim(line.substr(start, comma - start)));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    have_header = true;
    break;
  }
  if (!have_header) throw RecordingError(path + ": no header row");
  if (auto fmt = rec.meta("format"); fmt && *fmt != "mls-recording/1")
    throw RecordingError(path + ": format '" + *fmt + "' is not mls-recording/1");
  const std::size_t header_line = line_no;
  for (std::size_t i = 0; i < rec.names.size(); ++i) {
    if (rec.names[i].empty())
      throw RecordingError(where(path, header_line) + "column " + std::to_string(i + 1) +
                           " has no name");
    for (std::size_t j = 0; j < i; ++j)
      if (rec.names[j] == rec.names[i])
        throw RecordingError(where(path, header_line) + "column '" + rec.names[i] +
                             "' appears twice");
  }
  for (const auto& r : required)
    if (!rec.has(r)) {
      std::string have;
      for (const auto& n : rec.names) have += (have.empty() ? "" : ", ") + n;
      throw RecordingError(where(path, header_line) + "missing required column '" + r +
                           "' (header has: " + have + ")");
    }

  const std::size_t ncol = rec.names.size();
  rec.columns.assign(ncol, {});
  const std::size_t estimate = text.size() / (ncol * 8 + 1);
  for (auto& c : rec.columns) c.reserve(estimate);
  std::size_t t_col = ncol;
  for (std::size_t i = 0; i < ncol; ++i)
    if (rec.names[i] == "t_s") t_col = i;
  double last_t = -std::numeric_limits<double>::infinity();

  while (next_line(line)) {
    if (line.empty() || line.front() == '#') continue;
    std::size_t start = 0;
    for (std::size_t c = 0; c < ncol; ++c) {
      std::size_t comma = line.find(',', start);
      if (comma == std::string_view::npos) {
        if (c + 1 != ncol)
          throw RecordingError(where(path, line_no) + "has " + std::to_string(c + 1) +
                               " fields, header has " + std::to_string(ncol));
        comma = line.size();
      } else if (c + 1 == ncol) {
        throw RecordingError(where(path, line_no) + "has more fields than the header's " +
                             std::to_string(ncol));
      }
      std::string_view field = line.substr(start, comma - start);
      while (!field.empty() && field.front() == ' ') field.remove_prefix(1);
      while (!field.empty() && field.back() == ' ') field.remove_suffix(1);
      double v = std::numeric_limits<double>::quiet_NaN();
      if (!field.empty()) {
        if (field.front() == '+') field.remove_prefix(1);
        auto [p, ec] = std::from_chars(field.data(), field.data() + field.size(), v);
        if (ec != std::errc() || p != field.data() + field.size() || !std::isfinite(v))
          throw RecordingError(where(path, line_no) + "column " + std::to_string(c + 1) + " (" +
                               rec.names[c] + "): '" + std::string(field) +
                               "' is not a number");
      }
      if (c == t_col) {
        if (std::isnan(v))
          throw RecordingError(where(path, line_no) + "column " + std::to_string(c + 1) +
                               " (t_s): time is missing");
        if (v < last_t) {
          std::ostringstream s;
          s << where(path, line_no) << "column " << c + 1 << " (t_s): time decreases (" << v
            << " after " << last_t << ")";
          throw RecordingError(s.str());
        }
        last_t = v;
      }
      rec.columns[c].push_back(v);
      start = comma + 1;
    }
  }
  return rec;
}

struct RecordingWriter::Impl {
  std::FILE* f = nullptr;
  std::string path;
  std::size_t ncol = 0;
};

RecordingWriter::RecordingWriter(const std::string& path,
                                 const std::vector<std::pair<std::string, std::string>>& metadata,
                                 const std::vector<std::string>& names)
    : impl_(new Impl) {
  impl_->path = path;
  impl_->ncol = names.size();
  impl_->f = std::fopen(path.c_str(), "w");
  if (!impl_->f) {
    delete impl_;
    throw std::runtime_error(path + ": cannot write");
  }
  std::fprintf(impl_->f, "# format: mls-recording/1\n");
  for (const auto& [k, v] : metadata)
    if (k != "format") std::fprintf(impl_->f, "# %s: %s\n", k.c_str(), v.c_str());
  for (std::size_t i = 0; i < names.size(); ++i)
    std::fprintf(impl_->f, "%s%s", i ? "," : "", names[i].c_str());
  std::fprintf(impl_->f, "\n");
}

RecordingWriter::~RecordingWriter() {
  if (impl_->f) std::fclose(impl_->f);
  delete impl_;
}

void RecordingWriter::write_row(const double* values, std::size_t count) {
  if (count != impl_->ncol) throw std::logic_error("RecordingWriter: row width differs from header");
  char buf[32];
  for (std::size_t i = 0; i < count; ++i) {
    if (i) std::fputc(',', impl_->f);
    if (std::isnan(values[i])) continue;
    auto [p, ec] = std::to_chars(buf, buf + sizeof buf, values[i]);
    std::fwrite(buf, 1, static_cast<std::size_t>(p - buf), impl_->f);
  }
  std::fputc('\n', impl_->f);
}

void RecordingWriter::close() {
  if (impl_->f) {
    const bool bad = std::ferror(impl_->f) != 0;
    const bool close_failed = std::fclose(impl_->f) != 0;
    impl_->f = nullptr;
    if (bad || close_failed) throw std::runtime_error(impl_->path + ": write failed");
  }
}

void write_recording(const std::string& path, const Recording& rec) {
  RecordingWriter w(path, rec.metadata, rec.names);
  std::vector<double> row(rec.names.size());
  for (std::size_t r = 0; r < rec.rows(); ++r) {
    for (std::size_t c = 0; c < row.size(); ++c) row[c] = rec.columns[c][r];
    w.write_row(row.data(), row.size());
  }
  w.close();
}

}  // namespace maglead
