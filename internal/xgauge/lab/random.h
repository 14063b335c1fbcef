// Random streams for simulations that give the same numbers at any thread
// count.
//
// Every random quantity of the virtual lab is drawn from a stream keyed by
// the user's seed and ids that say what it is for, for example (seed, photon
// noise, shot 3, row 812). A parallel loop over rows gives each row its own
// stream, so no number depends on how the rows are split among threads or in
// which order they run. Nothing is shared, so nothing needs a lock.
//
// Why hand-written: the engines of <random> are too heavy to create once per
// row and purpose (std::mt19937_64 holds 2.5 KB of state and is seeded
// properly only through a seed_seq pass over it). SplitMix64 (Steele, Lea and
// Flood 2014; the seeder of the xoshiro family) is one 64-bit word, a new
// stream is one hash, and its output passes BigCrush.
//
// SplitMix64 satisfies std::uniform_random_bit_generator, so the standard
// distributions accept it. Their algorithms are not fixed by the C++
// standard, only their distributions: libstdc++'s std::normal_distribution
// (Marsaglia's polar method) and std::poisson_distribution (Devroye's
// rejection method) give the same values for the same engine output on every
// run, but libc++ or MSVC give other, equally valid, values. Results are
// therefore bit-identical for one standard library, not across them. A
// distribution object may cache a value between calls (the polar method makes
// two normals at a time): create it beside its stream, one per row.
//
// Stream overlap: all streams walk the same cycle of 2^64 states from a
// hashed start. k streams of n draws each overlap with probability about
// k^2 n / 2^64, below 1e-7 for a 4096-row image of 4096 columns with a few
// draws per pixel, even across thousands of shots.
#pragma once

#include <concepts>
#include <cstdint>
#include <random>

namespace xgauge {

// The SplitMix64 output function: a bijection of 64-bit words that mixes every
// input bit into every output bit.
constexpr uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

class SplitMix64 {
 public:
  using result_type = uint64_t;

  // A generator starting from a raw state; prefer stream().
  explicit constexpr SplitMix64(uint64_t state) : state_(state) {}

  // The stream keyed by `seed` and the ids (purpose, shot, row, ...). Distinct
  // keys give unrelated streams; the order of the ids matters, and
  // stream(s, a) differs from stream(s, a, 0).
  // The key absorbs one id per round, key = mix64(key + gamma) ^ id, so that
  // (seed, ids) -> key is one-to-one in the last id and scrambles the others.
  template <std::convertible_to<uint64_t>... Ids>
  static constexpr SplitMix64 stream(uint64_t seed, Ids... ids) {
    uint64_t key = seed;
    ((key = mix64(key + kGamma) ^ static_cast<uint64_t>(ids)), ...);
    return SplitMix64(mix64(key + kGamma));
  }

  static constexpr result_type min() { return 0; }
  static constexpr result_type max() { return ~uint64_t{0}; }
  constexpr result_type operator()() {
    state_ += kGamma;
    return mix64(state_);
  }

  // Uniform in [0, 1), the 53 high bits of one draw.
  constexpr double uniform() { return static_cast<double>((*this)() >> 11) * 0x1.0p-53; }

 private:
  static constexpr uint64_t kGamma = 0x9e3779b97f4a7c15ULL;  // 2^64 / golden ratio, odd
  uint64_t state_;
};

static_assert(std::uniform_random_bit_generator<SplitMix64>);

}  // namespace xgauge
