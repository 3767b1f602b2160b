#include "maglead/recording/recording.hpp"

#include <string.h>  // NOLINT(modernize-deprecated-headers): memrchr is GNU, not in <cstring>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <sstream>
#include <string_view>

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

/// The file in blocks of whole lines, read 1 MiB at a time: a one-hour recording (~400 MB) is
/// never held in memory at once, and each block is parsed while it is still in the CPU cache.
/// Every block ends with '\n'; a last line without one gets one, so the parser needs no end test.
class LineBlocks {
 public:
  explicit LineBlocks(const std::string& path) : path_(path) {
    f_ = std::fopen(path.c_str(), "rb");
    if (!f_) throw RecordingError(path + ": cannot open");
  }
  ~LineBlocks() { std::fclose(f_); }
  LineBlocks(const LineBlocks&) = delete;
  LineBlocks& operator=(const LineBlocks&) = delete;

  /// Size in bytes (0 if unknown), to size the columns before reading.
  std::uintmax_t size() const {
    std::error_code ec;
    const auto n = std::filesystem::file_size(path_, ec);
    return ec ? 0 : n;
  }

  /// The next block of complete lines; false at the end of the file.
  bool next(std::string_view& block) {
    std::memmove(buf_.data(), buf_.data() + used_, have_ - used_);
    have_ -= used_;
    used_ = 0;
    while (true) {
      while (!eof_ && have_ < buf_.size()) {
        const std::size_t n = std::fread(buf_.data() + have_, 1, buf_.size() - have_, f_);
        have_ += n;
        if (n == 0) {
          if (std::ferror(f_)) throw RecordingError(path_ + ": cannot read");
          eof_ = true;
        }
      }
      if (eof_ && have_ > 0 && buf_[have_ - 1] != '\n') {
        if (have_ == buf_.size()) buf_.resize(buf_.size() + 1);
        buf_[have_++] = '\n';
      }
      if (have_ == 0) return false;
      const void* nl = memrchr(buf_.data(), '\n', have_);
      if (nl) {
        used_ = static_cast<std::size_t>(static_cast<const char*>(nl) - buf_.data()) + 1;
        block = std::string_view(buf_.data(), used_);
        return true;
      }
      buf_.resize(buf_.size() * 2);  // one line longer than the buffer
    }
  }

 private:
  std::string path_;
  std::FILE* f_ = nullptr;
  std::vector<char> buf_ = std::vector<char>(std::size_t{1} << 20);
  std::size_t have_ = 0, used_ = 0;
  bool eof_ = false;
};

/// The numeric rows after the header. Well-formed rows (no spaces, no '+', no comment) take a
/// fast path straight through the block with std::from_chars; any other line, and every
/// malformed one, goes through parse_line, which alone decides what is an error and says so.
class RowParser {
 public:
  RowParser(Recording& rec, std::size_t line_no)
      : rec_(rec), ncol_(rec.names.size()), line_no_(line_no), row_(ncol_) {
    for (std::size_t i = 0; i < ncol_; ++i)
      if (rec.names[i] == "t_s") t_col_ = i;
  }

  /// Parses whole lines; `block` ends with '\n'.
  void parse_block(std::string_view block) {
    const char* p = block.data();
    const char* const end = p + block.size();
    while (p < end) {
      const char* const line = p;
      ++line_no_;
      if (!fast_row(p, end)) {
        const char* nl =
            static_cast<const char*>(std::memchr(line, '\n', static_cast<std::size_t>(end - line)));
        parse_line(std::string_view(line, static_cast<std::size_t>(nl - line)));
        p = nl + 1;
      }
    }
  }

  /// One line (without its '\n'): blank and '#' lines are skipped, a row is checked and kept.
  void parse_line(std::string_view line) {
    const std::string& path = rec_.path;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty() || line.front() == '#') return;
    std::size_t start = 0;
    for (std::size_t c = 0; c < ncol_; ++c) {
      std::size_t comma = line.find(',', start);
      if (comma == std::string_view::npos) {
        if (c + 1 != ncol_)
          throw RecordingError(where(path, line_no_) + "has " + std::to_string(c + 1) +
                               " fields, header has " + std::to_string(ncol_) + ": column " +
                               std::to_string(c + 2) + " (" + rec_.names[c + 1] + ") is missing");
        comma = line.size();
      } else if (c + 1 == ncol_) {
        throw RecordingError(where(path, line_no_) + "has more fields than the header's " +
                             std::to_string(ncol_) + ": column " + std::to_string(ncol_ + 1) +
                             " has no name in the header");
      }
      std::string_view field = line.substr(start, comma - start);
      while (!field.empty() && field.front() == ' ') field.remove_prefix(1);
      while (!field.empty() && field.back() == ' ') field.remove_suffix(1);
      double v = std::numeric_limits<double>::quiet_NaN();
      if (!field.empty()) {
        if (field.front() == '+') field.remove_prefix(1);
        auto [p, ec] = std::from_chars(field.data(), field.data() + field.size(), v);
        if (ec != std::errc() || p != field.data() + field.size() || !std::isfinite(v))
          throw RecordingError(where(path, line_no_) + "column " + std::to_string(c + 1) + " (" +
                               rec_.names[c] + "): '" + std::string(field) + "' is not a number");
      }
      if (c == t_col_) {
        if (std::isnan(v))
          throw RecordingError(where(path, line_no_) + "column " + std::to_string(c + 1) +
                               " (t_s): time is missing");
        if (v < last_t_) {
          std::ostringstream s;
          s << where(path, line_no_) << "column " << c + 1 << " (t_s): time decreases (" << v
            << " after " << last_t_ << ")";
          throw RecordingError(s.str());
        }
      }
      row_[c] = v;
      start = comma + 1;
    }
    keep_row();
  }

 private:
  /// A plain row: fields that are empty or exactly a finite number, ',' between, "\n" or
  /// "\r\n" after, time not missing and not decreasing. Advances `p` past it and keeps it;
  /// false (row not kept, `p` wherever it stopped) for anything else.
  bool fast_row(const char*& p, const char* end) {
    if (*p == '\n' || *p == '\r' || *p == '#') return false;
    for (std::size_t c = 0; c < ncol_; ++c) {
      double v = std::numeric_limits<double>::quiet_NaN();
      if (*p != ',' && *p != '\n' && *p != '\r') {
        const auto [q, ec] = std::from_chars(p, end, v);
        if (ec != std::errc() || !std::isfinite(v)) return false;
        p = q;  // < end: the block's last '\n' is never part of a number
      }
      row_[c] = v;
      if (c + 1 < ncol_) {
        if (*p != ',') return false;
        ++p;
      }
    }
    if (*p == '\r') ++p;  // not the block's last byte, which is '\n'
    if (*p != '\n') return false;
    if (t_col_ < ncol_ && !(row_[t_col_] >= last_t_)) return false;  // missing or decreasing
    ++p;
    keep_row();
    return true;
  }

  void keep_row() {
    if (t_col_ < ncol_) last_t_ = row_[t_col_];
    for (std::size_t c = 0; c < ncol_; ++c) rec_.columns[c].push_back(row_[c]);
  }

  Recording& rec_;
  std::size_t ncol_;
  std::size_t t_col_ = std::numeric_limits<std::size_t>::max();
  std::size_t line_no_;
  std::vector<double> row_;
  double last_t_ = -std::numeric_limits<double>::infinity();
};

/// Rows a file of `bytes` will hold, judged by the average length of the sample's lines.
std::size_t estimate_rows(std::uintmax_t bytes, std::string_view sample, std::size_t ncol) {
  sample = sample.substr(0, std::size_t{1} << 16);
  const auto lines = static_cast<std::size_t>(std::count(sample.begin(), sample.end(), '\n'));
  const double per_line = lines > 0
                              ? static_cast<double>(sample.size()) / static_cast<double>(lines)
                              : static_cast<double>(ncol * 8 + 1);
  return static_cast<std::size_t>(static_cast<double>(bytes) / per_line * 1.1) + 16;
}

}  // namespace

Recording read_recording(const std::string& path, const std::vector<std::string>& required) {
  LineBlocks blocks(path);
  Recording rec;
  rec.path = path;

  // Metadata and the header row, one line at a time; `block` keeps what follows the header.
  std::size_t line_no = 0;
  std::string_view block;
  bool have_header = false;
  while (!have_header && blocks.next(block)) {
    while (!block.empty()) {
      const std::size_t nl = block.find('\n');
      std::string_view line = block.substr(0, nl);
      block.remove_prefix(nl + 1);
      ++line_no;
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
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
  const std::size_t estimate = estimate_rows(blocks.size(), block, ncol);
  for (auto& c : rec.columns) c.reserve(estimate);

  RowParser rows(rec, header_line);
  rows.parse_block(block);
  while (blocks.next(block)) rows.parse_block(block);
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
  if (count != impl_->ncol)
    throw std::logic_error("RecordingWriter: row width differs from header");
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
