// Finite checks by bit pattern: -ffast-math lets the compiler assume std::isfinite is always true.
#pragma once
#include <cstdint>
#include <cstring>

namespace spikegs {
inline bool is_finite(float v) {
  std::uint32_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  return (bits & 0x7f800000u) != 0x7f800000u;
}
inline bool is_finite(double v) {
  std::uint64_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  return (bits & 0x7ff0000000000000ull) != 0x7ff0000000000000ull;
}
template <typename T>
bool all_finite(const T* values, long count) {
  for (long i = 0; i < count; ++i)
    if (!is_finite(values[i])) return false;
  return true;
}
}  // namespace spikegs
