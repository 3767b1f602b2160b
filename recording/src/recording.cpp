#include "maglead/recording/recording.hpp"

#include <fcntl.h>
#include <string.h>  // NOLINT(modernize-deprecated-headers): memrchr is GNU, not in <cstring>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <sstream>
#include <string_view>
#include <utility>

#include "maglead/fileio/atomic_file.hpp"

namespace maglead {

bool Recording::has(const std::string& name) const {
  for (const auto& n : names)
    if (n == name) return true;
  return false;
}

const std::vector<double>& Recording::column(const std::string& name) const {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return columns[i];
  throw MissingColumnError(
      path + ": no column '" + name + "'" + missing_column_detail(names, name, "columns read"),
      name);
}

namespace {

/// The quantity of a `<quantity>_<unit>` name: the name less its unit (compound units such as
/// N·m and m/s included), "" when it has none.
std::string quantity_of(const std::string& name) {
  // With an SI prefix too (drive_torque_mn_m: millinewton metres, nut_vel_mm_s).
  for (const char* unit : {"n_m", "m_s", "rad_s", "n_s_per_m"})
    for (const char* prefix : {"", "m", "k", "u", "c"}) {
      const std::string suffix = std::string("_") + prefix + unit;
      if (name.ends_with(suffix)) return name.substr(0, name.size() - suffix.size());
    }
  const std::size_t cut = name.rfind('_');
  return cut == std::string::npos ? std::string() : name.substr(0, cut);
}

std::string unit_words(const std::string& name, const std::string& quantity) {
  std::string unit = name.substr(quantity.size() + 1);  // returned when no word is known
  constexpr std::pair<const char*, const char*> kWords[] = {
      {"m", "metres"},    {"n", "newtons"},         {"s", "seconds"},
      {"rad", "radians"}, {"n_m", "newton metres"}, {"m_s", "metres per second"},
      {"a", "amperes"}};
  for (const auto& [u, words] : kWords)
    if (unit == u) return words;
  return unit;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

std::string stand_in_hint(const std::string& name, const std::string& wanted) {
  const std::string quantity = quantity_of(wanted);
  if (name == wanted || quantity.empty()) return "";
  // Upper case first: T_S is t_s as a spreadsheet capitalised it, not t in another unit.
  if (lower(name) == wanted)
    return "column names are lower case: rename '" + name + "' to '" + wanted + "'";
  const std::string units = unit_words(wanted, quantity);
  if (lower(name) == lower(quantity))
    return "'" + name + "' has no unit in its name: if it is in " + units + ", name it '" + wanted +
           "' (docs/recording-format.md)";
  if (lower(quantity_of(name)) == lower(quantity))
    return "'" + name + "' looks like " + wanted + " in another unit: convert it to " + units +
           " and name it '" + wanted + "' (units are SI: docs/recording-format.md)";
  return "";
}

std::string missing_column_detail(const std::vector<std::string>& names, const std::string& wanted,
                                  const std::string& listed) {
  std::string have;
  for (const auto& n : names) have += (have.empty() ? "" : ", ") + n;
  std::string out = " (" + listed + ": " + (have.empty() ? std::string("no column") : have) + ")";
  for (const auto& n : names)
    if (const std::string hint = stand_in_hint(n, wanted); !hint.empty()) return out + "; " + hint;
  return out;
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

/// For a field that is a word for a missing value (NA, NaN, null): how to write one.
std::string missing_value_hint(std::string_view field) {
  const std::string word = lower(std::string(field));
  for (const char* missing : {"na", "nan", "-nan", "null", "none", "#n/a", "n/a"})
    if (word == missing)
      return ": a missing value is an empty field: write nothing between the commas (R: "
             "write.csv(x, na = \"\"))";
  return "";
}

std::string where(const std::string& path, std::size_t line) {
  return path + ":" + std::to_string(line) + ": ";
}

/// Index of the first byte of `s` that is not UTF-8 text (a control character other than tab and
/// CR, or a malformed, overlong or surrogate sequence); npos when all is text.
std::size_t first_non_text_byte(std::string_view s) {
  for (std::size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      if ((c < 0x20 && c != '\t' && c != '\r') || c == 0x7F) return i;
      ++i;
      continue;
    }
    const std::size_t len = (c >= 0xC2 && c <= 0xDF)   ? 2
                            : (c >= 0xE0 && c <= 0xEF) ? 3
                            : (c >= 0xF0 && c <= 0xF4) ? 4
                                                       : 0;
    if (len == 0 || i + len > s.size()) return i;
    for (std::size_t k = 1; k < len; ++k)
      if ((static_cast<unsigned char>(s[i + k]) & 0xC0) != 0x80) return i;
    const auto c1 = static_cast<unsigned char>(s[i + 1]);
    if ((c == 0xE0 && c1 < 0xA0) || (c == 0xED && c1 > 0x9F) || (c == 0xF0 && c1 < 0x90) ||
        (c == 0xF4 && c1 > 0x8F))
      return i;
    i += len;
  }
  return std::string_view::npos;
}

/// Refuses a line that is not text, naming the first bad byte by value and column but never
/// echoing the line: raw binary on a terminal garbles it, and says nothing to the reader.
void require_text(std::string_view line, const std::string& path, std::size_t line_no) {
  const std::size_t bad = first_non_text_byte(line);
  if (bad == std::string_view::npos) return;
  char hex[8];
  std::snprintf(hex, sizeof hex, "0x%02X",
                static_cast<unsigned>(static_cast<unsigned char>(line[bad])));
  throw RecordingError(where(path, line_no) + "byte " + hex + " at column " +
                       std::to_string(bad + 1) +
                       " is not UTF-8 text: a binary file or another encoding, not an "
                       "mls-recording/1 CSV (the line is not shown)");
}

/// The file in blocks of whole lines, read 1 MiB at a time: a one-hour recording (~400 MB) is
/// never held in memory at once, and each block is parsed while it is still in the CPU cache.
/// Every block ends with '\n', so the parser needs no end test; a last line without one is kept
/// apart (unterminated_tail): it may be a row torn by a crash.
class LineBlocks {
 public:
  explicit LineBlocks(const std::string& path) : path_(path) {
    f_ = std::fopen(path.c_str(), "rb");
    if (!f_) throw RecordingError(path + ": cannot open (" + std::strerror(errno) + ")");
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

  /// The file's last line when it has no line end (empty otherwise), known once next() is false.
  std::string& unterminated_tail() { return tail_; }

  /// The next block of complete lines, each ending with '\n'; false at the end of the file.
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
        // The last line has no line end: set aside for the caller to judge (torn or not).
        const void* last_nl = memrchr(buf_.data(), '\n', have_);
        const std::size_t keep =
            last_nl ? static_cast<std::size_t>(static_cast<const char*>(last_nl) - buf_.data()) + 1
                    : 0;
        tail_.assign(buf_.data() + keep, have_ - keep);
        have_ = keep;
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
  std::string tail_;
};

/// A column's slot when it is checked but not stored.
constexpr std::size_t kSkipped = std::numeric_limits<std::size_t>::max();

/// The numeric rows after the header. Well-formed rows (no spaces, no '+', no comment) take a
/// fast path straight through the block with std::from_chars; any other line, and every
/// malformed one, goes through parse_line, which alone decides what is an error and says so.
class RowParser {
 public:
  /// `header` names every column of the file; `slot` says where each is stored in rec.columns
  /// (kSkipped: checked, not stored).
  RowParser(Recording& rec, std::vector<std::string> header, std::vector<std::size_t> slot,
            std::size_t line_no)
      : rec_(rec),
        header_(std::move(header)),
        slot_(std::move(slot)),
        ncol_(header_.size()),
        line_no_(line_no),
        row_(ncol_) {
    for (std::size_t i = 0; i < ncol_; ++i)
      if (header_[i] == "t_s") t_col_ = i;
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

  /// The file's last line when it has no line end; returns a warning, empty when none. Every
  /// row of an mls-recording/1 file ends with one (RecordingWriter writes a row per write()), so
  /// there the line is torn by a crash or power cut: dropped. A file without the format line (a
  /// third-party CSV) keeps the line when it reads as a row and drops it when not.
  std::string parse_last_line(std::string_view line, bool own_format) {
    ++line_no_;
    if (line.find_first_not_of(" \t\r") == std::string_view::npos) return "";
    std::string why = "every row of an mls-recording/1 file ends with one";
    if (!own_format) {
      try {
        parse_line(line);
        return "";
      } catch (const RecordingError& e) {
        why = e.what();
        const std::string prefix = where(rec_.path, line_no_);
        if (why.rfind(prefix, 0) == 0) why.erase(0, prefix.size());
      }
    }
    return where(rec_.path, line_no_) +
           "the last line has no line end and was dropped as torn by a crash or power cut (" + why +
           ")";
  }

  /// One line (without its '\n'): blank and '#' lines are skipped, a row is checked and kept.
  void parse_line(std::string_view line) {
    const std::string& path = rec_.path;
    require_text(line, path, line_no_);  // before any message quotes a field
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty() || line.front() == '#') return;
    std::size_t start = 0;
    for (std::size_t c = 0; c < ncol_; ++c) {
      std::size_t comma = line.find(',', start);
      if (comma == std::string_view::npos) {
        if (c + 1 != ncol_)
          throw RecordingError(where(path, line_no_) + "has " + std::to_string(c + 1) +
                               " fields, header has " + std::to_string(ncol_) + ": column " +
                               std::to_string(c + 2) + " (" + header_[c + 1] + ") is missing");
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
                               header_[c] + "): '" + std::string(field) + "' is not a number" +
                               missing_value_hint(field));
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
    for (std::size_t c = 0; c < ncol_; ++c)
      if (slot_[c] != kSkipped) rec_.columns[slot_[c]].push_back(row_[c]);
  }

  Recording& rec_;
  std::vector<std::string> header_;
  std::vector<std::size_t> slot_;
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

namespace {

/// One line before the rows: metadata (`# key: value`) is kept, blank lines skipped. True when it
/// was the header row, whose names are then in rec.names.
bool take_head_line(Recording& rec, std::string_view line, std::size_t line_no) {
  // A UTF-8 byte-order mark (Excel's "CSV UTF-8" writes one) is no part of the text.
  if (line_no == 1 && line.starts_with("\xEF\xBB\xBF")) line.remove_prefix(3);
  require_text(line, rec.path, line_no);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  if (line.empty()) return false;
  if (line.front() == '#') {
    std::string_view body = line.substr(1);
    const std::size_t colon = body.find(':');
    if (colon != std::string_view::npos)
      rec.metadata.emplace_back(trim(body.substr(0, colon)), trim(body.substr(colon + 1)));
    return false;
  }
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    std::string name = trim(line.substr(start, comma - start));
    // R's write.csv and pandas' QUOTE_ALL put names in double quotes: the name is inside.
    if (name.size() >= 2 && name.front() == '"' && name.back() == '"')
      name = name.substr(1, name.size() - 2);
    rec.names.push_back(std::move(name));
    if (comma == std::string_view::npos) return true;
    start = comma + 1;
  }
}

/// What a header row looks like, for the errors that find none.
constexpr const char* kHeaderExample =
    "after its '# key: value' lines a recording names its columns in one comma-separated row, "
    "e.g. t_s,screw_angle_rad,nut_pos_m,load_force_n for the actuator or t_s,pos_m,drive_force_n "
    "for an axis (docs/recording-format.md)";

/// Metadata and the header row; returns the header's line number. `block` keeps what follows the
/// header in the current block.
std::size_t read_head(Recording& rec, LineBlocks& blocks, std::string_view& block) {
  std::size_t line_no = 0;
  while (blocks.next(block)) {
    while (!block.empty()) {
      const std::size_t nl = block.find('\n');
      const std::string_view line = block.substr(0, nl);
      block.remove_prefix(nl + 1);
      if (take_head_line(rec, line, ++line_no)) return line_no;
    }
  }
  // A header (or a file) without a line end: the header is whole if the names are.
  std::string& tail = blocks.unterminated_tail();
  if (!tail.empty() && take_head_line(rec, tail, ++line_no)) {
    tail.clear();
    return line_no;
  }
  // An empty file (a logger that never wrote, a wrong file): say what the header looks like.
  throw RecordingError(rec.path + ": no header row: " + kHeaderExample);
}

void check_header(const Recording& rec, std::size_t header_line,
                  const std::vector<std::string>& required) {
  const std::string& path = rec.path;
  if (auto fmt = rec.meta("format"); fmt && *fmt != "mls-recording/1")
    throw RecordingError(path + ": format '" + *fmt + "' is not mls-recording/1");
  // A row of numbers where the names belong: data without its header (an export that left it
  // out), which would otherwise be read as columns named "0", "138.23", ….
  const auto is_number = [](const std::string& s) {
    char* end = nullptr;
    std::strtod(s.c_str(), &end);
    return !s.empty() && end == s.c_str() + s.size();
  };
  if (std::all_of(rec.names.begin(), rec.names.end(), is_number))
    throw RecordingError(where(path, header_line) + "no header row: this row is numbers ('" +
                         rec.names.front() + "', …) where the column names belong; " +
                         kHeaderExample);
  for (std::size_t i = 0; i < rec.names.size(); ++i) {
    if (rec.names[i].empty())
      throw RecordingError(where(path, header_line) + "column " + std::to_string(i + 1) +
                           " has no name");
    for (std::size_t j = 0; j < i; ++j)
      if (rec.names[j] == rec.names[i])
        throw RecordingError(where(path, header_line) + "column '" + rec.names[i] +
                             "' appears twice");
  }
  // A spreadsheet's export with another separator reads as one column: say so, not "missing".
  if (rec.names.size() == 1)
    for (const char sep : {';', '\t', ' '})
      if (rec.names[0].find(sep) != std::string::npos)
        throw RecordingError(where(path, header_line) + "the header is one column ('" +
                             rec.names[0].substr(0, 60) + "'): fields are separated by '" +
                             (sep == '\t' ? std::string("\\t") : std::string(1, sep)) +
                             "', an mls-recording/1 separates them by commas");
  for (const auto& r : required)
    if (!rec.has(r))
      throw MissingColumnError(where(path, header_line) + "missing required column '" + r + "'" +
                                   missing_column_detail(rec.names, r),
                               r);
}

/// Narrows rec.names to the columns `keep` chooses and the required ones (all when no `keep`);
/// returns each header column's slot in rec.columns, kSkipped for one not stored.
std::vector<std::size_t> choose_columns(Recording& rec, const std::vector<std::string>& required,
                                        const ColumnChoice& keep) {
  std::vector<std::size_t> slot(rec.names.size());
  if (!keep) {
    for (std::size_t c = 0; c < slot.size(); ++c) slot[c] = c;
    return slot;
  }
  std::vector<std::string> wanted = keep(rec);
  wanted.insert(wanted.end(), required.begin(), required.end());
  // A column that stands in for a wanted one the header lacks (pos_mm for pos_m) is kept too:
  // the reader's error about the missing one then names it and what to convert.
  const auto stands_in = [&](const std::string& name) {
    return std::any_of(wanted.begin(), wanted.end(), [&](const std::string& w) {
      return !rec.has(w) && !stand_in_hint(name, w).empty();
    });
  };
  std::vector<std::string> kept;
  for (std::size_t c = 0; c < slot.size(); ++c) {
    const bool wants = std::find(wanted.begin(), wanted.end(), rec.names[c]) != wanted.end() ||
                       stands_in(rec.names[c]);
    slot[c] = wants ? kept.size() : kSkipped;
    if (wants) kept.push_back(rec.names[c]);
  }
  rec.names = std::move(kept);
  return slot;
}

}  // namespace

Recording read_recording(const std::string& path, const std::vector<std::string>& required,
                         const ColumnChoice& keep) {
  LineBlocks blocks(path);
  Recording rec;
  rec.path = path;
  std::string_view block;
  const std::size_t header_line = read_head(rec, blocks, block);
  check_header(rec, header_line, required);

  std::vector<std::string> header = rec.names;  // every column: rows are checked against it
  std::vector<std::size_t> slot = choose_columns(rec, required, keep);
  rec.columns.assign(rec.names.size(), {});
  const std::size_t estimate = estimate_rows(blocks.size(), block, header.size());
  for (auto& c : rec.columns) c.reserve(estimate);

  RowParser rows(rec, std::move(header), std::move(slot), header_line);
  rows.parse_block(block);
  while (blocks.next(block)) rows.parse_block(block);
  const std::string& tail = blocks.unterminated_tail();
  if (!tail.empty()) {
    std::string warning = rows.parse_last_line(tail, rec.meta("format").has_value());
    if (!warning.empty()) {
      std::fprintf(stderr, "warning: %s\n", warning.c_str());
      rec.warnings.push_back(std::move(warning));
    }
  }
  check_plausible_units(rec);
  make_evenly_sampled(rec);
  return rec;
}

/// Streaming: rows go to the file itself, one write() per row, so they leave the process whole
/// and at once. Whole: rows collect in blocks written to an AtomicFile, renamed in by close().
struct RecordingWriter::Impl {
  std::string path;
  std::size_t ncol = 0;
  WriteMode mode = WriteMode::streaming;
  int fd = -1;                         // streaming
  std::unique_ptr<AtomicFile> atomic;  // whole
  std::string pending;                 // text not yet written
  std::chrono::steady_clock::time_point last_sync = std::chrono::steady_clock::now();

  void put_pending() {
    if (mode == WriteMode::whole) {
      atomic->write(pending);
    } else if (!write_all(fd, pending)) {
      throw std::runtime_error(path + ": write failed (" + std::strerror(errno) + ")");
    }
    pending.clear();
  }

  /// Streaming: to disk when the interval has passed since the last sync.
  void sync_if_due() {
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - last_sync).count() < kRecordingSyncInterval_s) return;
    if (::fdatasync(fd) != 0)
      throw std::runtime_error(path + ": cannot sync to disk (" + std::strerror(errno) + ")");
    last_sync = now;
  }
};

RecordingWriter::RecordingWriter(const std::string& path,
                                 const std::vector<std::pair<std::string, std::string>>& metadata,
                                 const std::vector<std::string>& names)
    : RecordingWriter(path, metadata, names, WriteMode::streaming) {}

RecordingWriter::RecordingWriter(const std::string& path,
                                 const std::vector<std::pair<std::string, std::string>>& metadata,
                                 const std::vector<std::string>& names, WriteMode mode)
    : impl_(new Impl) {
  std::unique_ptr<Impl> impl(impl_);  // freed if the constructor throws
  impl->path = path;
  impl->ncol = names.size();
  impl->mode = mode;
  // Its folder is made, as analyze's and report's --out folders are ("--out out/push.csv" on a
  // fresh checkout); a folder that cannot be made fails at the open below, with its reason.
  if (const auto dir = std::filesystem::path(path).parent_path(); !dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
  }
  if (mode == WriteMode::whole) {
    impl->atomic = std::make_unique<AtomicFile>(path);
  } else {
    impl->fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (impl->fd < 0)
      throw std::runtime_error(path + ": cannot write (" + std::strerror(errno) + ")");
  }
  std::string& h = impl->pending;
  h = "# format: mls-recording/1\n";
  for (const auto& [k, v] : metadata)
    if (k != "format") h += "# " + k + ": " + v + "\n";
  for (std::size_t i = 0; i < names.size(); ++i) h += (i ? "," : "") + names[i];
  h += "\n";
  if (mode == WriteMode::streaming) impl->put_pending();
  static_cast<void>(impl.release());
}

RecordingWriter::~RecordingWriter() {
  if (impl_->fd >= 0) {
    try {
      impl_->put_pending();
    } catch (const std::exception&) {  // NOLINT(bugprone-empty-catch): a destructor cannot report
    }
    ::close(impl_->fd);
  }
  delete impl_;  // a whole file never closed: AtomicFile removes its temporary file
}

void RecordingWriter::write_row(const double* values, std::size_t count) {
  if (count != impl_->ncol)
    throw std::logic_error("RecordingWriter: row width differs from header");
  std::string& out = impl_->pending;
  char buf[32];
  for (std::size_t i = 0; i < count; ++i) {
    if (i) out += ',';
    if (std::isnan(values[i])) continue;
    auto [p, ec] = std::to_chars(buf, buf + sizeof buf, values[i]);
    out.append(buf, static_cast<std::size_t>(p - buf));
  }
  out += '\n';
  if (impl_->mode == WriteMode::streaming) {
    impl_->put_pending();  // the whole row in one write()
    impl_->sync_if_due();
  } else if (out.size() >= (std::size_t{1} << 20)) {
    impl_->put_pending();
  }
}

void RecordingWriter::close() {
  Impl& m = *impl_;
  if (m.mode == WriteMode::whole) {
    if (!m.atomic) return;
    m.put_pending();
    m.atomic->commit();
    m.atomic.reset();
    return;
  }
  if (m.fd < 0) return;
  m.put_pending();
  const int fd = std::exchange(m.fd, -1);
  const bool synced = ::fdatasync(fd) == 0;
  if (::close(fd) != 0 || !synced)
    throw std::runtime_error(m.path + ": write failed (" + std::strerror(errno) + ")");
}

void write_recording(const std::string& path, const Recording& rec) {
  RecordingWriter w(path, rec.metadata, rec.names, WriteMode::whole);
  std::vector<double> row(rec.names.size());
  for (std::size_t r = 0; r < rec.rows(); ++r) {
    for (std::size_t c = 0; c < row.size(); ++c) row[c] = rec.columns[c][r];
    w.write_row(row.data(), row.size());
  }
  w.close();
}

}  // namespace maglead
