#include "maglead/fileio/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <utility>

namespace maglead {

namespace {

std::runtime_error io_error(const std::string& path, const char* what) {
  return std::runtime_error(path + ": " + what + " (" + std::strerror(errno) + ")");
}

/// A name in the target's directory no other writer uses at the same time: the process id and a
/// counter. A leading '.' keeps it out of directory listings and globs like *.csv.
std::string temporary_name_for(const std::string& path) {
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path p(path);
  const std::string name = "." + p.filename().string() + ".tmp-" + std::to_string(::getpid()) +
                           "-" + std::to_string(counter++);
  return (p.parent_path() / name).string();
}

/// Syncs the directory holding `path` so that a rename in it is on disk.
void sync_directory_of(const std::string& path) {
  std::string dir = std::filesystem::path(path).parent_path().string();
  if (dir.empty()) dir = ".";
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;  // a directory we may not open: the rename is done, only its sync is not
  ::fsync(fd);
  ::close(fd);
}

}  // namespace

bool write_all(int fd, std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
  return true;
}

AtomicFile::AtomicFile(std::string path)
    : path_(std::move(path)), temp_(temporary_name_for(path_)) {
  // 0666 through the umask, as a plain open would give the target.
  fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd_ < 0) throw io_error(path_, "cannot write");
}

AtomicFile::~AtomicFile() {
  if (fd_ >= 0) {
    ::close(fd_);
    ::unlink(temp_.c_str());
  }
}

void AtomicFile::write(std::string_view bytes) {
  if (fd_ < 0) throw std::logic_error(path_ + ": written after commit");
  if (!write_all(fd_, bytes)) throw io_error(path_, "write failed");
}

void AtomicFile::commit() {
  if (fd_ < 0) throw std::logic_error(path_ + ": committed twice");
  if (::fsync(fd_) != 0) throw io_error(path_, "cannot sync to disk");
  const int fd = std::exchange(fd_, -1);
  if (::close(fd) != 0 || ::rename(temp_.c_str(), path_.c_str()) != 0) {
    const auto e = io_error(path_, "cannot put in place");
    ::unlink(temp_.c_str());
    throw e;
  }
  sync_directory_of(path_);
}

void write_file_atomically(const std::string& path, std::string_view content) {
  AtomicFile f(path);
  f.write(content);
  f.commit();
}

}  // namespace maglead
