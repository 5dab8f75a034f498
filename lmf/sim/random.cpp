#include "lmf/sim/random.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace lmf::sim {

uint64_t derive_seed(uint64_t seed, uint64_t stream) {
  uint64_t z = seed + 0x9E3779B97F4A7C15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

double Rng::uniform01() {
  return static_cast<double>(engine_() >> 11) * 0x1.0p-53;
}

uint64_t Rng::uniform_index(uint64_t n) {
  if (n == 0) throw std::invalid_argument("Rng::uniform_index: n must be positive");
  // Rejection keeps the result exactly uniform (no modulo bias).
  const uint64_t limit = UINT64_MAX - UINT64_MAX % n;
  uint64_t v = engine_();
  while (v >= limit) v = engine_();
  return v % n;
}

int Rng::uniform_int(int lo, int hi) {
  if (hi < lo) throw std::invalid_argument("Rng::uniform_int: empty range");
  const auto span = static_cast<uint64_t>(static_cast<int64_t>(hi) - static_cast<int64_t>(lo) + 1);
  return static_cast<int>(static_cast<int64_t>(lo) + static_cast<int64_t>(uniform_index(span)));
}

double Rng::normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  // Box–Muller; 1 - u lies in (0, 1], so the log is finite.
  const double u1 = 1.0 - uniform01();
  const double u2 = uniform01();
  const double r = std::sqrt(-2.0 * std::log(u1));
  const double a = 2.0 * std::numbers::pi * u2;
  spare_ = r * std::sin(a);
  has_spare_ = true;
  return r * std::cos(a);
}

}  // namespace lmf::sim
