#pragma once
// Output files that appear whole or not at all: written under a temporary name in the target's
// directory, synced, then renamed over the target (rename is atomic within one file system), so
// a crash or a power cut never leaves a half-written model, report or recording that a later
// `serve --model` or `analyze` would take for a whole one.
#include <string>
#include <string_view>

namespace maglead {

/// One file being written. Nothing is visible under `path` until commit(); a file never committed
/// (an exception, an early return) is removed by the destructor and `path` is left as it was.
class AtomicFile {
 public:
  /// Creates the temporary file beside `path`; throws std::runtime_error naming `path` and why.
  explicit AtomicFile(std::string path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  /// Appends bytes (all of them; a short write is retried). Throws on an I/O error.
  void write(std::string_view bytes);
  /// fsync, rename over the target, fsync the directory (so the rename itself survives a power
  /// cut). Throws on failure, leaving the target untouched.
  void commit();

  const std::string& path() const { return path_; }
  /// The temporary file's name, for libraries that can only write to a name of their own.
  const std::string& temp_path() const { return temp_; }

 private:
  std::string path_, temp_;
  int fd_ = -1;
};

/// Writes `content` to `path` through an AtomicFile.
void write_file_atomically(const std::string& path, std::string_view content);

/// Writes all of `bytes` to `fd`, retrying short writes and EINTR; false (errno set) on error.
bool write_all(int fd, std::string_view bytes);

}  // namespace maglead
