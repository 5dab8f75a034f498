#include "lmf/io/text_file.hpp"

#include <zlib.h>

#include <algorithm>
#include <charconv>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <system_error>
#include <vector>

namespace lmf::io {
namespace {

std::string errno_text() { return errno != 0 ? std::strerror(errno) : "out of memory"; }

}  // namespace

void for_each_line(const std::filesystem::path& file,
                   const std::function<void(const std::string& text, std::size_t line_number)>& on_line) {
  for_each_line(file, [&](const std::string& text, std::size_t line_number, bool) { on_line(text, line_number); });
}

void for_each_line(
    const std::filesystem::path& file,
    const std::function<void(const std::string& text, std::size_t line_number, bool terminated)>& on_line) {
  errno = 0;
  gzFile in = gzopen(file.c_str(), "rb");
  if (in == nullptr) throw std::runtime_error("cannot open " + file.string() + ": " + errno_text());
  struct Closer {
    gzFile f;
    ~Closer() { gzclose(f); }
  } closer{in};
  gzbuffer(in, 1u << 17);

  // gzread and an explicit split on '\n' (not gzgets + strlen): a NUL byte in
  // hostile input must not end a line early and glue it to the next one,
  // which would shift every later line number in error messages.
  std::string line;
  std::size_t line_number = 0;
  const auto emit = [&](bool terminated) {
    ++line_number;
    while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
    on_line(line, line_number, terminated);
    line.clear();
  };
  std::vector<char> chunk(1 << 16);
  for (;;) {
    const int n = gzread(in, chunk.data(), static_cast<unsigned>(chunk.size()));
    if (n <= 0) {
      int err = Z_OK;
      const char* message = gzerror(in, &err);
      if (n < 0 || (err != Z_OK && err != Z_STREAM_END)) {
        throw std::runtime_error("error reading " + file.string() + " after line " + std::to_string(line_number) +
                                 ": " + (err == Z_ERRNO ? std::string(std::strerror(errno)) : message));
      }
      break;
    }
    const char* data = chunk.data();
    const auto size = static_cast<std::size_t>(n);
    std::size_t start = 0;
    while (start < size) {
      const void* newline = std::memchr(data + start, '\n', size - start);
      if (newline == nullptr) {
        line.append(data + start, size - start);  // a line longer than one chunk, or the last line
        break;
      }
      const auto end = static_cast<std::size_t>(static_cast<const char*>(newline) - data);
      line.append(data + start, end - start);
      emit(true);
      start = end + 1;
    }
  }
  if (!line.empty()) emit(false);  // a last line without newline
}

void write_text_file(const std::filesystem::path& file, const std::string& text, bool gzip) {
  gzip = gzip || file.extension() == ".gz";
  errno = 0;
  // "T": zlib's transparent (uncompressed) writing, so both cases share one path.
  gzFile out = gzopen(file.c_str(), gzip ? "wb6" : "wbT");
  if (out == nullptr) throw std::runtime_error("cannot open " + file.string() + " for writing: " + errno_text());
  std::size_t done = 0;
  while (done < text.size()) {
    const std::size_t len = std::min<std::size_t>(text.size() - done, 1u << 20);
    const int written = gzwrite(out, text.data() + done, static_cast<unsigned>(len));
    if (written <= 0) {
      int err = Z_OK;
      const std::string message = gzerror(out, &err);
      const std::string reason = err == Z_ERRNO ? std::string(std::strerror(errno)) : message;
      gzclose(out);
      throw std::runtime_error("error writing " + file.string() + ": " + reason);
    }
    done += static_cast<std::size_t>(written);
  }
  if (gzclose(out) != Z_OK) throw std::runtime_error("error closing " + file.string());
}

std::string seconds_text(int64_t utime) {
  const bool negative = utime < 0;
  const uint64_t magnitude = negative ? 0 - static_cast<uint64_t>(utime) : static_cast<uint64_t>(utime);
  char buf[48];
  std::snprintf(buf, sizeof buf, "%s%" PRIu64 ".%06" PRIu64, negative ? "-" : "", magnitude / 1000000u,
                magnitude % 1000000u);
  return buf;
}

std::vector<std::string_view> split_fields(std::string_view text) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
  std::vector<std::string_view> fields;
  std::size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && is_space(text[i])) ++i;
    const std::size_t start = i;
    while (i < text.size() && !is_space(text[i])) ++i;
    if (i > start) fields.push_back(text.substr(start, i - start));
  }
  return fields;
}

std::optional<double> parse_double(std::string_view field) {
  const char* begin = field.data();
  const char* end = begin + field.size();
  if (begin != end && *begin == '+') ++begin;  // from_chars rejects a leading '+'
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(begin, end, v);
  if (ec != std::errc() || ptr != end || begin == end) return std::nullopt;
  return v;
}

}  // namespace lmf::io
