// An exact, versioned binary archive of a GlobalMap: everything that decides
// its future fusions, so a map read back continues BIT-IDENTICALLY to the one
// written (the fusion server's durable state, issue 6).
//
// What is stored: the GlobalMapConfig; the GlobalState (entities with ids,
// kinds, locations, lengths, parents and offsets, the next id, the capacity of
// the covariance buffer and the lower triangle of P, diagonal included); every
// robot record (joined, next_seq, min_seq, frames still needed, local maps
// waiting in its queue, fused seqs, frame history); submaps, paired graph
// edges, sightings still pending, and the flags. Doubles are stored as their
// IEEE-754 bits, so nothing is rounded. The capacity is restored too, so P's
// columns sit at the same strides as before (Eigen's kernels then see the same
// memory layout).
//
// File layout (all integers and doubles little-endian, the host order checked
// at compile time):
//   magic      8 bytes   "LMFGMAP\0" (a framed archive of another kind has another magic)
//   version    u32       kGlobalMapArchiveVersion
//   length     u64       payload bytes
//   payload    length bytes
//   crc32      u32       zlib CRC-32 of magic, version, length and payload
// The payload is a sequence of fixed-size fields and counted arrays in the
// order of write_global_map() (global_map_archive.cpp documents it field by
// field). A version this build does not know, a wrong magic, a short file, a
// checksum mismatch, a count that cannot fit in the remaining bytes or a map
// that breaks an invariant (offsets, parents, ids) throw ArchiveError; nothing
// half-read is ever returned.
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

#include "lmf/fusion/global_map.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"

namespace lmf::fusion {

// 2: GlobalMapConfig::local_map_covariance_scale. 3: robot footprints
// (GlobalMapConfig::footprint_radius_m and the recorded positions). 4: crossing
// segments (GlobalMapConfig::crossing_*, FusionReport::crossing_segments_removed).
inline constexpr std::uint32_t kGlobalMapArchiveVersion = 4;

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
  std::uint8_t u8();
  bool boolean();  // 0 or 1, anything else is corrupt
  std::uint32_t u32();
  std::int32_t i32();
  std::uint64_t u64();
  std::int64_t i64();
  double f64();
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
  const char* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
  std::string context_;
};

// The frame around a payload (see the layout above): magic (exactly 8 chars),
// version, length, payload, CRC-32.
void write_framed(std::ostream& out, std::string_view magic, std::uint32_t version, std::string_view payload);
// Reads one framed archive; returns its payload and sets `version`. Throws
// ArchiveError for a wrong magic, a version other than `this_version` (older
// archives are not converted: refused by name rather than misread), a length
// above `max_length`, a short stream or a checksum mismatch.
std::string read_framed(std::istream& in, std::string_view magic, std::uint32_t this_version, std::uint32_t& version,
                        std::uint64_t max_length = std::uint64_t{1} << 40);

// The whole map as a framed archive (magic "LMFGMAP\0").
void write_archive(const GlobalMap& map, std::ostream& out);
GlobalMap read_archive(std::istream& in);

// The map's payload only, to embed it in another archive (the server's state
// snapshot). read_global_map() checks the map's invariants.
void write_global_map(ArchiveWriter& w, const GlobalMap& map);
GlobalMap read_global_map(ArchiveReader& r);

// Pieces the server archives next to the map.
void write_local_map(ArchiveWriter& w, const LocalMapSnapshot& s);
LocalMapSnapshot read_local_map(ArchiveReader& r);
void write_fusion_report(ArchiveWriter& w, const FusionReport& report);
FusionReport read_fusion_report(ArchiveReader& r);

// Field-by-field bitwise equality (a restored map must be configured exactly
// like the one the caller would build).
bool same_config(const GlobalMapConfig& a, const GlobalMapConfig& b);

// Grants the archive functions access to GlobalMap's and GlobalState's
// private members (named as a friend there); defined in the .cpp only.
class GlobalMapArchive;

}  // namespace lmf::fusion
