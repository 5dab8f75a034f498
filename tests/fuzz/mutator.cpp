#include "mutator.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <limits>
#include <numbers>
#include <string_view>

namespace lmf::fuzz {

namespace {

void put_be(Bytes& data, std::size_t at, std::uint64_t value, std::size_t width) {
  for (std::size_t i = 0; i < width && at + i < data.size(); ++i) {
    data[at + i] = static_cast<std::uint8_t>(value >> (8 * (width - 1 - i)));
  }
}

std::uint64_t get_be(const Bytes& data, std::size_t at, std::size_t width) {
  std::uint64_t value = 0;
  for (std::size_t i = 0; i < width; ++i) value = (value << 8) | (at + i < data.size() ? data[at + i] : 0u);
  return value;
}

constexpr std::array<std::int64_t, 22> kCounts = {
    0, 1, 2, 3, -1, -2, 255, 256, 511, 512, 513, 4096, 4097, 8192, 8193, 65535, 65536, 65537,
    std::numeric_limits<std::int32_t>::max(), std::numeric_limits<std::int32_t>::min(),
    std::numeric_limits<std::int32_t>::max() / 8, 0x10000000};

constexpr std::array<std::int64_t, 8> kInt64s = {
    0, 1, -1, std::numeric_limits<std::int64_t>::max(), std::numeric_limits<std::int64_t>::min(),
    std::numeric_limits<std::int32_t>::max(), 1'000'000'000'000'000, -1'000'000};

const std::array<double, 16> kDoubles = {
    std::numeric_limits<double>::quiet_NaN(), -std::numeric_limits<double>::quiet_NaN(),
    std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
    std::numeric_limits<double>::max(), std::numeric_limits<double>::lowest(),
    std::numeric_limits<double>::denorm_min(), -0.0, 0.0, 1e300, -1e-300, 1e6 + 1,
    std::numbers::pi + 1e-6, -std::numbers::pi, 2.0 * std::numbers::pi, -1.0};

const std::array<float, 8> kFloats = {
    std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
    -std::numeric_limits<float>::infinity(), std::numeric_limits<float>::max(), -1.0f, 0.0f, -0.0f, 1e-45f};

constexpr std::array<std::string_view, 31> kTokens = {
    "nan", "-nan", "inf", "-inf", "infinity", "1e309", "-1e309", "1e300", "-1e200", "1e40", "1e-320", "0", "-0", "-1", "1", "2", "4096",
    "4097", "99999999999999999999", "9e12", "9.1e12", "0x10", "+", "-", "1.5.2", "FLASER", "ROBOTLASER1", "ODOM",
    "PARAM", "#", ""};

constexpr std::array<std::uint8_t, 6> kBytes = {0x00, 0x01, 0x7f, 0x80, 0xff, 0x20};

bool is_space(std::uint8_t c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

}  // namespace

Mutator::Mutator(const std::vector<Bytes>& seeds, std::size_t max_length) : seeds_(seeds), max_length_(max_length) {
  if (seeds_.empty()) fail("Mutator: no seeds");
}

Bytes Mutator::input(std::uint64_t run_seed, std::uint64_t index) {
  // Independent stream per input (splitmix-style scramble of seed and index).
  std::uint64_t z = run_seed * 0x9e3779b97f4a7c15ULL + index + 1;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  rng_.seed(z ^ (z >> 31));
  Bytes data = seeds_[rng_() % seeds_.size()];
  int stacked = 1;
  while (stacked < 8 && rng_() % 2 == 0) ++stacked;
  for (int i = 0; i < stacked; ++i) mutate_once(data);
  if (data.size() > max_length_) data.resize(max_length_);
  return data;
}

std::size_t Mutator::offset(const Bytes& data) { return static_cast<std::size_t>(rng_() % data.size()); }

void Mutator::mutate_once(Bytes& data) {
  if (data.empty()) {
    insert_bytes(data);
    return;
  }
  // Weights: the structured mutations (counts, numbers) dominate because
  // they get past the decoders' size checks.
  switch (rng_() % 20) {
    case 0: flip_bit(data); break;
    case 1: set_byte(data); break;
    case 2: insert_bytes(data); break;
    case 3: erase_bytes(data); break;
    case 4:
    case 5:
    case 6: set_count(data); break;
    case 7: set_int64(data); break;
    case 8:
    case 9: set_double(data); break;
    case 10:
    case 11: scale_double(data); break;
    case 12: set_float(data); break;
    case 13: splice(data); break;
    case 14: copy_chunk(data); break;
    case 15: truncate(data); break;
    case 16:
    case 17: insert_token(data); break;
    default: replace_token(data); break;
  }
}

void Mutator::flip_bit(Bytes& data) { data[offset(data)] ^= static_cast<std::uint8_t>(1u << (rng_() % 8)); }

void Mutator::set_byte(Bytes& data) {
  data[offset(data)] = rng_() % 2 ? kBytes[rng_() % kBytes.size()] : static_cast<std::uint8_t>(rng_());
}

void Mutator::insert_bytes(Bytes& data) {
  const std::size_t at = data.empty() ? 0 : static_cast<std::size_t>(rng_() % (data.size() + 1));
  const std::size_t n = 1 + rng_() % (rng_() % 4 == 0 ? 256 : 8);
  const bool repeat = rng_() % 2 == 0;
  const auto value = static_cast<std::uint8_t>(rng_());
  Bytes chunk(n);
  for (auto& b : chunk) b = repeat ? value : static_cast<std::uint8_t>(rng_());
  data.insert(data.begin() + static_cast<std::ptrdiff_t>(at), chunk.begin(), chunk.end());
}

void Mutator::erase_bytes(Bytes& data) {
  const std::size_t at = offset(data);
  const std::size_t n = std::min(data.size() - at, 1 + static_cast<std::size_t>(rng_() % (rng_() % 4 == 0 ? 256 : 8)));
  data.erase(data.begin() + static_cast<std::ptrdiff_t>(at), data.begin() + static_cast<std::ptrdiff_t>(at + n));
}

// A big-endian int32 that looks like a count or an id (0..70000) is the
// likeliest count field: prefer it, then set a boundary value or nudge it.
void Mutator::set_count(Bytes& data) {
  if (data.size() < 4) return flip_bit(data);
  std::size_t at = static_cast<std::size_t>(rng_() % (data.size() - 3));
  for (int tries = 0; tries < 32; ++tries) {
    const std::size_t candidate = static_cast<std::size_t>(rng_() % (data.size() - 3));
    const auto v = static_cast<std::int32_t>(get_be(data, candidate, 4));
    if (v > 0 && v <= 70000) {
      at = candidate;
      break;
    }
  }
  std::int64_t value = 0;
  if (rng_() % 2 == 0) {
    value = kCounts[rng_() % kCounts.size()];
  } else {
    const auto current = static_cast<std::int32_t>(get_be(data, at, 4));
    const auto delta = static_cast<std::int64_t>(rng_() % 33) - 16;
    value = static_cast<std::int64_t>(current) + delta;
  }
  put_be(data, at, static_cast<std::uint32_t>(static_cast<std::int32_t>(value)), 4);
}

void Mutator::set_int64(Bytes& data) {
  put_be(data, offset(data), static_cast<std::uint64_t>(kInt64s[rng_() % kInt64s.size()]), 8);
}

void Mutator::set_double(Bytes& data) {
  put_be(data, offset(data), std::bit_cast<std::uint64_t>(kDoubles[rng_() % kDoubles.size()]), 8);
}

// Covariances and poses are doubles: changing one value a little keeps the
// message decodable and probes the symmetric/PSD/angle checks at their edges.
void Mutator::scale_double(Bytes& data) {
  if (data.size() < 8) return set_byte(data);
  const std::size_t at = static_cast<std::size_t>(rng_() % (data.size() - 7));
  const double v = std::bit_cast<double>(get_be(data, at, 8));
  static constexpr std::array<double, 8> kFactors = {-1.0, 2.0, 0.5, 1e10, 1e-10, 1.0 + 1e-8, -1e-3, 1e150};
  double out = v * kFactors[rng_() % kFactors.size()];
  if (rng_() % 4 == 0) out = v + (rng_() % 2 ? 1e-12 : -1e-12);
  put_be(data, at, std::bit_cast<std::uint64_t>(out), 8);
}

void Mutator::set_float(Bytes& data) {
  put_be(data, offset(data), std::bit_cast<std::uint32_t>(kFloats[rng_() % kFloats.size()]), 4);
}

void Mutator::splice(Bytes& data) {
  const Bytes& other = seeds_[rng_() % seeds_.size()];
  if (other.empty()) return truncate(data);
  const std::size_t cut = offset(data);
  const std::size_t from = static_cast<std::size_t>(rng_() % other.size());
  data.resize(cut);
  data.insert(data.end(), other.begin() + static_cast<std::ptrdiff_t>(from), other.end());
}

void Mutator::copy_chunk(Bytes& data) {
  const std::size_t from = offset(data);
  const std::size_t n = std::min(data.size() - from, 1 + static_cast<std::size_t>(rng_() % 64));
  const Bytes chunk(data.begin() + static_cast<std::ptrdiff_t>(from), data.begin() + static_cast<std::ptrdiff_t>(from + n));
  if (rng_() % 2 == 0) {
    const std::size_t to = static_cast<std::size_t>(rng_() % (data.size() + 1));
    data.insert(data.begin() + static_cast<std::ptrdiff_t>(to), chunk.begin(), chunk.end());
  } else {
    const std::size_t to = offset(data);
    for (std::size_t i = 0; i < n && to + i < data.size(); ++i) data[to + i] = chunk[i];
  }
}

void Mutator::truncate(Bytes& data) { data.resize(static_cast<std::size_t>(rng_() % (data.size() + 1))); }

void Mutator::insert_token(Bytes& data) {
  const std::string_view token = kTokens[rng_() % kTokens.size()];
  const std::size_t at = static_cast<std::size_t>(rng_() % (data.size() + 1));
  Bytes chunk;
  chunk.push_back(rng_() % 8 == 0 ? '\n' : ' ');
  chunk.insert(chunk.end(), token.begin(), token.end());
  data.insert(data.begin() + static_cast<std::ptrdiff_t>(at), chunk.begin(), chunk.end());
}

// The whitespace-separated field around a random position becomes a token.
void Mutator::replace_token(Bytes& data) {
  std::size_t begin = offset(data);
  if (is_space(data[begin])) return insert_token(data);
  while (begin > 0 && !is_space(data[begin - 1])) --begin;
  std::size_t end = begin;
  while (end < data.size() && !is_space(data[end])) ++end;
  const std::string_view token = kTokens[rng_() % kTokens.size()];
  data.erase(data.begin() + static_cast<std::ptrdiff_t>(begin), data.begin() + static_cast<std::ptrdiff_t>(end));
  data.insert(data.begin() + static_cast<std::ptrdiff_t>(begin), token.begin(), token.end());
}

}  // namespace lmf::fuzz
