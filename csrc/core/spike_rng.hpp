// Counter-based random numbers for the spike simulator: every draw is a pure function of
// (seed, counter), so results do not depend on the thread count or on how the work is chunked.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace spikegs {

// splitmix64's finalizer: a bijective 64-bit mix.
inline uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// 64 random bits for `counter` in the stream named by `key` (splitmix64 at position counter).
inline uint64_t random_bits(uint64_t key, uint64_t counter) {
  return mix64(key + counter * 0x9E3779B97F4A7C15ull);
}

// A uniform in (0, 1) from 32 random bits (24 of them used); the top value, whose + 0.5 rounds
// up to 2^24 in float, kept below 1.
inline float uniform_open(uint32_t bits) {
  return std::min((float(bits >> 8) + 0.5f) * (1.0f / 16777216.0f), 0x1.fffffep-1f);
}

struct NormalPair {
  float z0, z1;
};

// Two independent standard normals from 64 random bits (Box-Muller).
inline NormalPair normal_pair(uint64_t bits) {
  const float r = std::sqrt(-2.0f * std::log(uniform_open(uint32_t(bits))));
  const float a = 6.2831853071795864f * uniform_open(uint32_t(bits >> 32));
  const float c = std::cos(a);
  // sin(a) from cos(a): a separate sin call would fuse into a sincos that does not vectorize.
  const float s = std::sqrt(std::max(0.0f, 1.0f - c * c));
  return {r * c, a < 3.14159265358979f ? r * s : -r * s};
}

}  // namespace spikegs
