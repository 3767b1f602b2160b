#pragma once
// The `mls-recording/1` time-series format (docs/recording-format.md): CSV with `# key: value`
// metadata, one header row of `<quantity>_<unit>` names, numeric rows, empty field = missing.
#include <cstddef>
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

struct Recording {
  std::string path;  // where it was read from (for messages)
  std::vector<std::pair<std::string, std::string>> metadata;
  std::vector<std::string> names;
  std::vector<std::vector<double>> columns;  // column-major; NaN marks a missing value

  std::size_t rows() const { return columns.empty() ? 0 : columns.front().size(); }
  bool has(const std::string& name) const;
  /// Throws RecordingError naming the file and the missing column.
  const std::vector<double>& column(const std::string& name) const;
  std::vector<double>& add_column(const std::string& name, std::vector<double> values = {});
  std::optional<std::string> meta(const std::string& key) const;
  void set_meta(const std::string& key, const std::string& value);
};

/// Reads and validates a recording; `required` columns must be present. Time (`t_s`) must be
/// non-decreasing. Throws RecordingError on any malformed content.
Recording read_recording(const std::string& path, const std::vector<std::string>& required = {});

/// Writes a whole recording (format line first). Throws std::runtime_error on I/O failure.
void write_recording(const std::string& path, const Recording& rec);

/// Streams rows to a file as they come (recorders, simulators): nothing is held in memory.
class RecordingWriter {
 public:
  RecordingWriter(const std::string& path,
                  const std::vector<std::pair<std::string, std::string>>& metadata,
                  const std::vector<std::string>& names);
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;
  /// One row; NaN is written as an empty field.
  void write_row(const double* values, std::size_t count);
  void close();

 private:
  struct Impl;
  Impl* impl_;
};

}  // namespace maglead
