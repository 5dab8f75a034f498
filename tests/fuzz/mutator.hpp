// Deterministic random mutations for the standalone fuzz driver (lmf-fuzz).
//
// No coverage feedback: every input is a seed with 1..8 stacked mutations,
// drawn from a generator seeded by (run seed, input index), so input i of a
// run can be rebuilt alone (`lmf-fuzz <target> --seed S --only i`). The
// mutations aim at what the decoders check: LCM is big-endian with int32 array
// counts, so counts get boundary values and small offsets; doubles and floats
// get NaN, infinities, huge, tiny and negated values; CARMEN text gets number
// tokens (nan, inf, 1e309, -1, 4097, ...) and field insertions/deletions;
// buffers get truncated, extended, spliced with other seeds.
#pragma once

#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

#include "fuzz_support.hpp"

namespace lmf::fuzz {

class Mutator {
 public:
  // `seeds` must not be empty and must outlive the mutator.
  Mutator(const std::vector<Bytes>& seeds, std::size_t max_length);

  // The input of index `index` in the run seeded by `run_seed`.
  Bytes input(std::uint64_t run_seed, std::uint64_t index);

 private:
  void mutate_once(Bytes& data);
  std::size_t offset(const Bytes& data);  // a position inside data (data not empty)

  void flip_bit(Bytes& data);
  void set_byte(Bytes& data);
  void insert_bytes(Bytes& data);
  void erase_bytes(Bytes& data);
  void set_count(Bytes& data);
  void set_int64(Bytes& data);
  void set_double(Bytes& data);
  void scale_double(Bytes& data);
  void set_float(Bytes& data);
  void splice(Bytes& data);
  void copy_chunk(Bytes& data);
  void truncate(Bytes& data);
  void insert_token(Bytes& data);
  void replace_token(Bytes& data);

  const std::vector<Bytes>& seeds_;
  std::size_t max_length_;
  std::mt19937_64 rng_;
};

}  // namespace lmf::fuzz
