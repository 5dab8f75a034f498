#include "lmf/bag/wire_decoder.hpp"

#include <algorithm>
#include <bit>
#include <cstring>

namespace lmf::bag {

const char* to_string(MessageEncoding encoding) { return encoding == MessageEncoding::ros1 ? "ros1" : "cdr"; }

WireDecodeError::WireDecodeError(std::size_t offset, const std::string& what)
    : std::runtime_error("byte " + std::to_string(offset) + ": " + what), offset_(offset) {}

WireDecoder::WireDecoder(std::span<const std::uint8_t> bytes, MessageEncoding encoding)
    : bytes_(bytes), encoding_(encoding) {
  if (encoding_ != MessageEncoding::cdr) return;
  if (bytes_.size() < 4) throw WireDecodeError(0, "shorter than the 4-byte CDR encapsulation header");
  const std::uint16_t kind = static_cast<std::uint16_t>((bytes_[0] << 8) | bytes_[1]);
  if (kind != 0x0000 && kind != 0x0001) {
    throw WireDecodeError(0, "unsupported CDR encapsulation 0x" + std::to_string(kind) +
                                 " (plain CDR, big- or little-endian, is read)");
  }
  big_endian_ = kind == 0x0000;
  offset_ = origin_ = 4;
}

const std::uint8_t* WireDecoder::take(std::size_t size, std::size_t alignment, const char* what) {
  if (encoding_ == MessageEncoding::cdr && alignment > 1) {
    const std::size_t misalignment = (offset_ - origin_) % alignment;
    if (misalignment != 0) offset_ += alignment - misalignment;
  }
  if (offset_ > bytes_.size() || bytes_.size() - offset_ < size) {
    throw WireDecodeError(std::min(offset_, bytes_.size()),
                          std::string("message ends inside ") + what + " (" + std::to_string(size) + " bytes needed, " +
                              std::to_string(offset_ > bytes_.size() ? 0 : bytes_.size() - offset_) + " left)");
  }
  const std::uint8_t* p = bytes_.data() + offset_;
  offset_ += size;
  return p;
}

namespace {
template <typename T>
T load(const std::uint8_t* p, bool big_endian) {
  std::uint8_t b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
  T value;
  std::memcpy(&value, b, sizeof(T));
  return value;
}
}  // namespace

std::uint8_t WireDecoder::u8(const char* what) { return *take(1, 1, what); }
std::uint32_t WireDecoder::u32(const char* what) { return load<std::uint32_t>(take(4, 4, what), big_endian_); }
std::int32_t WireDecoder::i32(const char* what) { return load<std::int32_t>(take(4, 4, what), big_endian_); }
float WireDecoder::f32(const char* what) { return load<float>(take(4, 4, what), big_endian_); }
double WireDecoder::f64(const char* what) { return load<double>(take(8, 8, what), big_endian_); }

std::uint32_t WireDecoder::sequence_length(std::size_t min_element_bytes, const char* what) {
  const std::size_t at = offset_;
  const std::uint32_t n = u32(what);
  const std::size_t left = bytes_.size() - offset_;
  if (min_element_bytes > 0 && n > left / min_element_bytes) {
    throw WireDecodeError(at, std::string(what) + ": length " + std::to_string(n) + " exceeds the " +
                                  std::to_string(left) + " bytes left");
  }
  return n;
}

std::string WireDecoder::string(const char* what) {
  const std::size_t at = offset_;
  const std::uint32_t n = sequence_length(1, what);
  const std::uint8_t* p = take(n, 1, what);
  if (encoding_ == MessageEncoding::ros1) return {reinterpret_cast<const char*>(p), n};
  if (n == 0 || p[n - 1] != 0) throw WireDecodeError(at, std::string(what) + ": CDR string without its NUL");
  return {reinterpret_cast<const char*>(p), n - 1};
}

std::vector<float> WireDecoder::f32_sequence(const char* what) {
  const std::uint32_t n = sequence_length(4, what);
  std::vector<float> values(n);
  for (auto& v : values) v = f32(what);
  return values;
}

std::int64_t WireDecoder::time_ns(const char* what) {
  const std::int64_t sec = encoding_ == MessageEncoding::ros1 ? static_cast<std::int64_t>(u32(what)) : i32(what);
  const std::uint32_t nsec = u32(what);
  return sec * 1'000'000'000 + nsec;
}

}  // namespace lmf::bag
