// Portable random numbers for the simulator.
//
// std::mt19937_64 is fully specified by the standard, but the std:: distributions
// are not (std::normal_distribution differs between libstdc++, libc++ and MSVC),
// so the simulator draws through this class: uniform doubles from the top 53 bits
// of the engine, integers by rejection, Gaussians by Box–Muller. The same seed then
// gives the same files on every machine (up to the platform's libm in log/cos).
//
// Not thread-safe (one instance per stream).
#pragma once

#include <cstdint>
#include <random>

namespace lmf::sim {

// A well-mixed 64-bit value from a seed and a stream tag (splitmix64 finaliser),
// so that independent streams (routes, laser noise, odometry noise, people) of one
// seed do not depend on each other's draw counts.
uint64_t derive_seed(uint64_t seed, uint64_t stream);

class Rng {
 public:
  explicit Rng(uint64_t seed) : engine_(seed) {}

  // Uniform in [0, 1), 53 random bits.
  double uniform01();
  // Uniform in [a, b).
  double uniform(double a, double b) { return a + (b - a) * uniform01(); }
  // Uniform integer in [0, n); n > 0 (throws std::invalid_argument otherwise).
  uint64_t uniform_index(uint64_t n);
  // Uniform integer in [lo, hi]; lo <= hi.
  int uniform_int(int lo, int hi);
  // True with probability p.
  bool bernoulli(double p) { return uniform01() < p; }
  // Standard normal (Box–Muller; the second value of each pair is kept for the next call).
  double normal();
  // Normal with the given mean and standard deviation.
  double normal(double mean, double sigma) { return mean + sigma * normal(); }

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

}  // namespace lmf::sim
