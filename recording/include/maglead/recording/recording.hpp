#pragma once
// The `mls-recording/1` time-series format (docs/recording-format.md): CSV with `# key: value`
// metadata, one header row of `<quantity>_<unit>` names, numeric rows, empty field = missing.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace maglead {

/// A malformed recording. what() names the file, line and column.
class RecordingError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The load-cell column cannot be the load in newtons (another unit or the other sign, or one
/// value throughout): what() says what it more likely is. A command that compares with the load
/// cell judges nothing by it.
class LoadCellUnitError : public RecordingError {
 public:
  using RecordingError::RecordingError;
  /// A load cell reading `constant_n` throughout (stuck, unplugged): its wiring, not its unit.
  LoadCellUnitError(const std::string& what, double constant_n)
      : RecordingError(what), constant_n_(constant_n) {}
  /// The value a constant load cell reads; none for another unit or the other sign.
  std::optional<double> constant_n() const { return constant_n_; }

 private:
  std::optional<double> constant_n_;
};

/// A column a reader needs is not in the recording: what() lists the columns there are (and one
/// that looks like it in another unit); column() names the missing one, so a command can add what
/// it needs the column for.
class MissingColumnError : public RecordingError {
 public:
  MissingColumnError(const std::string& what, std::string column)
      : RecordingError(what), column_(std::move(column)) {}
  const std::string& column() const { return column_; }

 private:
  std::string column_;
};

/// What header column `name` is to a `wanted` one the header lacks, as a fix: "column names are
/// lower case: rename 'T_S' to 't_s'", the quantity without a unit (nut_pos), or the quantity in
/// another unit (nut_pos_mm, screw_angle_deg: what to convert); "" when it is none of them.
std::string stand_in_hint(const std::string& name, const std::string& wanted);

/// " (header has: a, b, c)" (`listed` says what the names are) and, where one of `names` is
/// `wanted` in another unit or without one (nut_pos_mm for nut_pos_m), what to convert and
/// rename: the tail of a missing-column error.
std::string missing_column_detail(const std::vector<std::string>& names, const std::string& wanted,
                                  const std::string& listed = "header has");

struct Recording {
  std::string path;  // where it was read from (for messages)
  std::vector<std::pair<std::string, std::string>> metadata;
  std::vector<std::string> names;
  std::vector<std::vector<double>> columns;  // column-major; NaN marks a missing value
  /// What the reader accepted but the user should know (a torn last line it dropped), each
  /// naming the file and line. read_recording also prints them to stderr.
  std::vector<std::string> warnings;

  std::size_t rows() const { return columns.empty() ? 0 : columns.front().size(); }
  bool has(const std::string& name) const;
  /// Throws MissingColumnError naming the file, the missing column and the columns stored.
  const std::vector<double>& column(const std::string& name) const;
  std::vector<double>& add_column(const std::string& name, std::vector<double> values = {});
  std::optional<std::string> meta(const std::string& key) const;
  void set_meta(const std::string& key, const std::string& value);
};

/// The columns a reader stores, chosen from the header: `header` has the path, metadata and
/// every name, no rows yet. Names the header lacks are ignored.
using ColumnChoice = std::function<std::vector<std::string>(const Recording& header)>;

/// Reads and validates a recording; `required` columns must be present. Time (`t_s`) must
/// increase (make_evenly_sampled refuses a repeated time stamp). Throws RecordingError on any
/// malformed content. With `keep`, only the columns it chooses (and the required ones) are stored,
/// in the file's order; the others are checked for syntax as every column is, but take no memory
/// and no units check (check_plausible_units); one that stands in for a chosen column the header
/// lacks (stand_in_hint) is kept for the error.
Recording read_recording(const std::string& path, const std::vector<std::string>& required = {},
                         const ColumnChoice& keep = {});

/// The rows' sample rate [Hz]: the header's sample_rate_hz where it states one (a logger's clock
/// is what the header names; the time stamps carry its rounding), else one over the median step
/// of t_s. Throws RecordingError for a header that is not a positive number or a t_s that does
/// not advance.
double sample_rate_hz(const Recording& rec);

/// Makes the rows one sample period apart (the header's sample_rate_hz, else the median step of
/// t_s), as every reader assumes: a gap of up to 10 rows or 50 ms, whichever is more (a recorder
/// that fell behind), is filled by linear interpolation, with a warning. Throws RecordingError for
/// a time stamp equal to the one before (naming the rows), rows that contradict the header's rate
/// (more rows than it allows, over a tenth of them missing) or a longer stretch missing, saying
/// what to fix. read_recording applies it.
void make_evenly_sampled(Recording& rec);

/// Bounds a column's values must keep to be in its unit at all (not a fit to any actuator).
struct PlausibleRanges {
  /// Positions (columns named `*pos*_m`) beyond ±this cannot be metres.
  double position_bound_m = 10.0;
  /// Where the bound comes from, quoted in the message.
  std::string position_bound_source = "a generous bound: no lead-screw actuator travels 10 m";
};

/// Refuses a recording whose columns cannot be in their units: a position beyond the bound, an
/// angle (`*_rad`) that jumps by more than 100 turns between rows, a time (`t_s`) whose median
/// step is 100x the header's sample period (sample_rate_hz). Throws RecordingError naming the
/// column, the values seen and the likely unit. read_recording applies the default ranges.
void check_plausible_units(const Recording& rec, const PlausibleRanges& ranges = {});

/// Rows missing between two rows `step_s` apart at `period_s` (0: none, jitter): the rule the
/// readers fill gaps by, and a recorder counts what it leaves for them by.
long rows_missing_between(double step_s, double period_s);

/// Writes a whole recording (format line first) atomically: under a temporary name, renamed into
/// place when complete. Throws std::runtime_error on I/O failure, leaving `path` as it was.
void write_recording(const std::string& path, const Recording& rec);

/// How a RecordingWriter puts rows on disk.
enum class WriteMode : std::uint8_t {
  /// A recorder: every row is written to `path` whole (one line per write) as it is given, and
  /// the file is synced to disk at least every kRecordingSyncInterval_s. A crash (SIGKILL) loses
  /// no row already given; a power cut at most the last interval's rows; neither tears an
  /// earlier row (the reader drops a torn last line with a warning).
  streaming,
  /// A file made in one go (simulate, write_recording): written under a temporary name and
  /// renamed into place by close(), so `path` holds the whole recording or what it held before.
  whole,
};

/// Longest time a streaming writer leaves written rows unsynced to disk.
inline constexpr double kRecordingSyncInterval_s = 1.0;

/// Writes rows to a file as they come: nothing is held in memory but the current block.
class RecordingWriter {
 public:
  /// A streaming writer (WriteMode::streaming).
  RecordingWriter(const std::string& path,
                  const std::vector<std::pair<std::string, std::string>>& metadata,
                  const std::vector<std::string>& names);
  RecordingWriter(const std::string& path,
                  const std::vector<std::pair<std::string, std::string>>& metadata,
                  const std::vector<std::string>& names, WriteMode mode);
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;
  /// One row; NaN is written as an empty field, a value as the shortest text that reads back
  /// as the same double (std::to_chars). Throws std::runtime_error on an I/O error.
  void write_row(const double* values, std::size_t count);
  /// Writes what is left, syncs and (WriteMode::whole) renames into place. A whole writer
  /// destroyed without close() leaves `path` untouched.
  void close();

 private:
  struct Impl;
  Impl* impl_;
};

}  // namespace maglead
