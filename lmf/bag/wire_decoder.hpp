// Decoding of one serialised ROS message's bytes, for the two encodings bags
// hold (docs/bags.md):
//   * ROS 1 serialisation (bag 2.0): little-endian, packed, no alignment;
//     strings and sequences are a uint32 length and their elements.
//   * CDR as ROS 2 writes it (XCDR1, "cdr" in MCAP, rosbag2's SQLite3): a
//     4-byte encapsulation header (0x00 0x00 big-endian, 0x00 0x01 little-endian,
//     then two option bytes); each primitive is aligned to its own size counted
//     from the end of the header; strings are a uint32 length that counts a
//     terminating NUL, then the characters and the NUL.
// Every read checks the remaining bytes: a short or malformed message throws
// WireDecodeError naming the byte offset and what was being read, never reads
// out of bounds.
//
// Pure, thread-safe (each decoder is used by one thread).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace lmf::bag {

enum class MessageEncoding { ros1, cdr };

// "ros1" or "cdr".
const char* to_string(MessageEncoding encoding);

class WireDecodeError : public std::runtime_error {
 public:
  WireDecodeError(std::size_t offset, const std::string& what);
  std::size_t offset() const { return offset_; }

 private:
  std::size_t offset_;
};

class WireDecoder {
 public:
  // Reads the encapsulation header first for CDR. Throws WireDecodeError.
  WireDecoder(std::span<const std::uint8_t> bytes, MessageEncoding encoding);

  MessageEncoding encoding() const { return encoding_; }
  std::size_t offset() const { return offset_; }

  std::uint8_t u8(const char* what);
  std::uint32_t u32(const char* what);
  std::int32_t i32(const char* what);
  float f32(const char* what);
  double f64(const char* what);
  std::string string(const char* what);
  // A sequence's length, checked against the bytes left for elements of at least
  // `min_element_bytes` each (so a corrupt length cannot ask for gigabytes).
  std::uint32_t sequence_length(std::size_t min_element_bytes, const char* what);
  std::vector<float> f32_sequence(const char* what);
  // A ROS time: ROS 1 uint32 sec + uint32 nsec, ROS 2 builtin_interfaces/Time
  // int32 sec + uint32 nanosec. Nanoseconds since the epoch.
  std::int64_t time_ns(const char* what);

 private:
  const std::uint8_t* take(std::size_t size, std::size_t alignment, const char* what);

  std::span<const std::uint8_t> bytes_;
  MessageEncoding encoding_;
  bool big_endian_ = false;
  std::size_t offset_ = 0;
  std::size_t origin_ = 0;  // CDR alignment counts from here (after the header)
};

}  // namespace lmf::bag
