// Exact binary archives: fixed-size little-endian fields (doubles as their
// IEEE-754 bits, so nothing is rounded), counted arrays and strings, and a frame
// that names, versions and checksums a payload. The global map's archive, the
// fusion server's state snapshots and journal, and the agent's state file are
// all written with these.
//
// Frame layout (all integers little-endian, the host order checked at compile
// time):
//   magic      8 bytes   names the kind of archive (e.g. "LMFGMAP\0")
//   version    u32       of that kind's payload layout
//   length     u64       payload bytes
//   payload    length bytes
//   crc32      u32       zlib CRC-32 of magic, version, length and payload
//
// Pure and synchronous; thread-safe for distinct objects.
#pragma once

#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <stdexcept>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf::io {

// A bad, short, corrupt or unknown-version archive (what and where).
class ArchiveError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Appends fields to a byte string (little-endian, doubles bit-exact).
class ArchiveWriter {
 public:
  explicit ArchiveWriter(std::string& out) : out_(out) {}
  void u8(std::uint8_t v) { out_.push_back(static_cast<char>(v)); }
  void boolean(bool v) { u8(v ? 1 : 0); }
  void u32(std::uint32_t v) { raw(&v, sizeof v); }
  void i32(std::int32_t v) { raw(&v, sizeof v); }
  void u64(std::uint64_t v) { raw(&v, sizeof v); }
  void i64(std::int64_t v) { raw(&v, sizeof v); }
  void f64(double v) { raw(&v, sizeof v); }
  void count(std::size_t n) { u64(n); }
  void pose(const Pose2& p);
  void matrix(const Eigen::MatrixXd& m);  // rows, cols, column-major values
  void matrix3(const Eigen::Matrix3d& m);
  void text(std::string_view s);          // length, bytes
  void raw(const void* data, std::size_t size);

 private:
  std::string& out_;
};

// Reads fields back; every read checks the remaining size and throws
// ArchiveError("<context>: truncated ...") instead of reading past the end.
class ArchiveReader {
 public:
  ArchiveReader(const char* data, std::size_t size, std::string context);
  std::uint8_t u8() { return scalar<std::uint8_t>(); }
  bool boolean();  // 0 or 1, anything else is corrupt
  std::uint32_t u32() { return scalar<std::uint32_t>(); }
  std::int32_t i32() { return scalar<std::int32_t>(); }
  std::uint64_t u64() { return scalar<std::uint64_t>(); }
  std::int64_t i64() { return scalar<std::int64_t>(); }
  double f64() { return scalar<double>(); }
  // An array count whose elements take at least `min_element_bytes` each: a
  // count larger than the remaining bytes allow is corrupt (never allocated).
  std::size_t count(std::size_t min_element_bytes);
  Pose2 pose();
  Eigen::MatrixXd matrix();
  Eigen::Matrix3d matrix3();
  std::string text();
  void raw(void* data, std::size_t size);
  std::size_t remaining() const { return size_ - pos_; }
  [[noreturn]] void fail(const std::string& what) const;

 private:
  // A fixed-size field in host (little-endian) order.
  template <typename T>
  T scalar() {
    T v{};
    raw(&v, sizeof v);
    return v;
  }

  const char* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
  std::string context_;
};

// zlib's CRC-32 of `size` bytes continued from `crc` (0 to start).
std::uint32_t crc32_update(std::uint32_t crc, const void* data, std::size_t size);

// The frame around a payload (see the layout above): magic (exactly 8 chars),
// version, length, payload, CRC-32.
void write_framed(std::ostream& out, std::string_view magic, std::uint32_t version, std::string_view payload);
// Reads one framed archive; returns its payload and sets `version`. Throws
// ArchiveError for a wrong magic, a version other than `this_version` (older
// archives are not converted: refused by name rather than misread), a length
// above `max_length`, a short stream or a checksum mismatch.
std::string read_framed(std::istream& in, std::string_view magic, std::uint32_t this_version, std::uint32_t& version,
                        std::uint64_t max_length = std::uint64_t{1} << 40);

}  // namespace lmf::io
