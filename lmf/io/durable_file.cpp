#include "lmf/io/durable_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

namespace lmf::io {
namespace {

[[noreturn]] void fail(const std::string& what, const std::filesystem::path& path) {
  throw FileError("cannot " + what + " " + path.string() + ": " + std::strerror(errno));
}

// Closes a descriptor on scope exit (a close error is not reported there:
// write_file_synced closes explicitly to check it).
struct Descriptor {
  int fd = -1;
  ~Descriptor() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

void write_all(int fd, std::string_view data, const std::filesystem::path& path) {
  while (!data.empty()) {
    const ssize_t n = ::write(fd, data.data(), data.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail("write", path);
    data.remove_prefix(static_cast<std::size_t>(n));
  }
}

void write_file_synced(const std::filesystem::path& path, std::string_view data) {
  Descriptor file{::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)};
  if (file.fd < 0) fail("create", path);
  write_all(file.fd, data, path);
  if (::fsync(file.fd) != 0) fail("fsync", path);
  const int fd = file.fd;
  file.fd = -1;
  if (::close(fd) != 0) fail("close", path);
}

void sync_directory(const std::filesystem::path& dir) {
  Descriptor folder{::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)};
  if (folder.fd < 0) fail("open folder", dir);
  if (::fsync(folder.fd) != 0) fail("fsync folder", dir);
}

void replace_file_durably(const std::filesystem::path& path, std::string_view data) {
  const std::filesystem::path temp = path.string() + ".tmp";
  write_file_synced(temp, data);
  if (::rename(temp.c_str(), path.c_str()) != 0) fail("rename onto", path);
  // The rename is durable once the folder's entry is.
  sync_directory(path.has_parent_path() ? path.parent_path() : std::filesystem::path("."));
}

}  // namespace lmf::io
