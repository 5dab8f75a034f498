// Writes that survive a crash or power loss (POSIX write/fsync/rename): the
// pieces the agent's state file and the fusion server's snapshots and journal
// are made of. Every failure throws FileError "cannot <what> <path>: <reason>",
// errno's text as the reason.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string_view>

namespace lmf::io {

class FileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Writes all of `data` to the open descriptor `fd` (retrying short writes and
// EINTR); `path` names the file in errors.
void write_all(int fd, std::string_view data, const std::filesystem::path& path);

// Creates or truncates `path`, writes `data`, fsyncs and closes it.
void write_file_synced(const std::filesystem::path& path, std::string_view data);

// fsyncs a directory, so the names created, renamed or removed in it are durable.
void sync_directory(const std::filesystem::path& dir);

// Replaces `path` atomically and durably: `path`.tmp written and synced, renamed
// onto `path`, the directory synced. On failure the old file is left as it was.
void replace_file_durably(const std::filesystem::path& path, std::string_view data);

}  // namespace lmf::io
