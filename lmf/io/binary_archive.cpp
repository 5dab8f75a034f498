#include "lmf/io/binary_archive.hpp"

#include <algorithm>
#include <bit>
#include <cstring>
#include <istream>
#include <limits>
#include <ostream>
#include <utility>

#include <zlib.h>

namespace lmf::io {

static_assert(std::endian::native == std::endian::little, "the archive stores host-order little-endian values");
static_assert(std::numeric_limits<double>::is_iec559, "the archive stores IEEE-754 doubles bit for bit");

std::uint32_t crc32_update(std::uint32_t crc, const void* data, std::size_t size) {
  const auto* bytes = static_cast<const Bytef*>(data);
  uLong c = crc;
  while (size > 0) {
    const auto chunk = static_cast<uInt>(std::min<std::size_t>(size, std::numeric_limits<uInt>::max()));
    c = crc32(c, bytes, chunk);
    bytes += chunk;
    size -= chunk;
  }
  return static_cast<std::uint32_t>(c);
}

// ---------------------------------------------------------------------------
// Writer / reader

void ArchiveWriter::raw(const void* data, std::size_t size) { out_.append(static_cast<const char*>(data), size); }

void ArchiveWriter::pose(const Pose2& p) {
  f64(p.x);
  f64(p.y);
  f64(p.phi);
}

void ArchiveWriter::matrix(const Eigen::MatrixXd& m) {
  i64(m.rows());
  i64(m.cols());
  raw(m.data(), static_cast<std::size_t>(m.size()) * sizeof(double));
}

void ArchiveWriter::matrix3(const Eigen::Matrix3d& m) { raw(m.data(), 9 * sizeof(double)); }

void ArchiveWriter::text(std::string_view s) {
  count(s.size());
  raw(s.data(), s.size());
}

ArchiveReader::ArchiveReader(const char* data, std::size_t size, std::string context)
    : data_(data), size_(size), context_(std::move(context)) {}

void ArchiveReader::fail(const std::string& what) const {
  throw ArchiveError(context_ + ": " + what + " (at byte " + std::to_string(pos_) + " of " + std::to_string(size_) +
                     ")");
}

void ArchiveReader::raw(void* data, std::size_t size) {
  if (size > remaining()) fail("truncated: " + std::to_string(size) + " more bytes needed");
  if (size > 0) std::memcpy(data, data_ + pos_, size);
  pos_ += size;
}

bool ArchiveReader::boolean() {
  const std::uint8_t v = u8();
  if (v > 1) fail("corrupt: a flag holds " + std::to_string(v));
  return v == 1;
}

std::size_t ArchiveReader::count(std::size_t min_element_bytes) {
  const std::uint64_t n = u64();
  if (min_element_bytes > 0 && n > remaining() / min_element_bytes) {
    fail("corrupt: a count of " + std::to_string(n) + " does not fit in the remaining bytes");
  }
  return static_cast<std::size_t>(n);
}

Pose2 ArchiveReader::pose() {
  Pose2 p;
  p.x = f64();
  p.y = f64();
  p.phi = f64();
  return p;
}

Eigen::MatrixXd ArchiveReader::matrix() {
  const std::int64_t rows = i64();
  const std::int64_t cols = i64();
  if (rows < 0 || cols < 0) fail("corrupt: a matrix of " + std::to_string(rows) + "x" + std::to_string(cols));
  if (rows > 0 && static_cast<std::uint64_t>(cols) > remaining() / sizeof(double) / static_cast<std::uint64_t>(rows)) {
    fail("truncated: a " + std::to_string(rows) + "x" + std::to_string(cols) + " matrix does not fit");
  }
  Eigen::MatrixXd m(rows, cols);
  raw(m.data(), static_cast<std::size_t>(m.size()) * sizeof(double));
  return m;
}

Eigen::Matrix3d ArchiveReader::matrix3() {
  Eigen::Matrix3d m;
  raw(m.data(), 9 * sizeof(double));
  return m;
}

std::string ArchiveReader::text() {
  std::string s(count(1), '\0');
  raw(s.data(), s.size());
  return s;
}

// ---------------------------------------------------------------------------
// Framing

void write_framed(std::ostream& out, std::string_view magic, std::uint32_t version, std::string_view payload) {
  if (magic.size() != 8) throw std::invalid_argument("write_framed: the magic must be 8 bytes");
  std::string head;
  ArchiveWriter w(head);
  w.raw(magic.data(), magic.size());
  w.u32(version);
  w.u64(payload.size());
  std::uint32_t crc = crc32_update(0, head.data(), head.size());
  crc = crc32_update(crc, payload.data(), payload.size());
  std::string tail;
  ArchiveWriter(tail).u32(crc);
  out.write(head.data(), static_cast<std::streamsize>(head.size()));
  out.write(payload.data(), static_cast<std::streamsize>(payload.size()));
  out.write(tail.data(), static_cast<std::streamsize>(tail.size()));
}

std::string read_framed(std::istream& in, std::string_view magic, std::uint32_t this_version, std::uint32_t& version,
                        std::uint64_t max_length) {
  const std::string what = "archive '" + std::string(magic.substr(0, magic.find('\0'))) + "'";
  char head[20];
  in.read(head, sizeof head);
  if (in.gcount() != static_cast<std::streamsize>(sizeof head)) {
    throw ArchiveError(what + ": truncated header (" + std::to_string(in.gcount()) + " of 20 bytes)");
  }
  if (std::string_view(head, 8) != magic) throw ArchiveError(what + ": wrong magic (not this kind of archive)");
  ArchiveReader h(head + 8, 12, what);
  version = h.u32();
  const std::uint64_t length = h.u64();
  if (version != this_version) {
    throw ArchiveError(what + ": " + (version != 0 && version < this_version ? "older" : "unknown") + " version " +
                       std::to_string(version) + " (this build reads version " + std::to_string(this_version) +
                       " only)");
  }
  if (length > max_length) throw ArchiveError(what + ": implausible payload length " + std::to_string(length));
  // Read in chunks: a corrupt length never allocates more than the stream holds.
  std::string payload;
  constexpr std::size_t kChunk = std::size_t{1} << 24;
  while (payload.size() < length) {
    const std::size_t want = static_cast<std::size_t>(std::min<std::uint64_t>(kChunk, length - payload.size()));
    const std::size_t had = payload.size();
    payload.resize(had + want);
    in.read(payload.data() + had, static_cast<std::streamsize>(want));
    if (in.gcount() != static_cast<std::streamsize>(want)) {
      throw ArchiveError(what + ": truncated payload (" + std::to_string(had + static_cast<std::size_t>(in.gcount())) +
                         " of " + std::to_string(length) + " bytes)");
    }
  }
  char tail[4];
  in.read(tail, sizeof tail);
  if (in.gcount() != static_cast<std::streamsize>(sizeof tail)) throw ArchiveError(what + ": truncated checksum");
  std::uint32_t stored = 0;
  std::memcpy(&stored, tail, sizeof stored);
  std::uint32_t crc = crc32_update(0, head, sizeof head);
  crc = crc32_update(crc, payload.data(), payload.size());
  if (crc != stored) throw ArchiveError(what + ": checksum mismatch (corrupt)");
  return payload;
}

}  // namespace lmf::io
