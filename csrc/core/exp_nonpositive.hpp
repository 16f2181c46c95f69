// e^x for x in [-87, 0], inline, so that the compositing loops vectorise without a call.
//
// glibc's vector expf is a call: every live register of the pixel loop is spilt around it, and it
// held 15 % of a training run's time (perf, the demo). Here x / ln 2 = n + f with n an integer
// and f in (-1/2, 1/2]; 2^f is a degree-6 polynomial (Chebyshev interpolation, relative error
// 2e-8 with float coefficients) and 2^n goes straight into the exponent bits. Every step is
// plain arithmetic, a truncating conversion and a shift, which SSE2, AVX2 and AVX-512 all have.
// Relative error over [-20, 0] 3.5e-7 with FMA, 1e-6 without (cpp_tests/test_exp.cpp), about that
// of rounding x / ln 2 to float. Double keeps `std::exp`: the gradient checks run in double.
#pragma once
#include <cmath>
#include <cstdint>

namespace spikegs::raster {

inline float exp_nonpositive(float x) {
  const float t = x * 1.44269504f;                // x / ln 2, in [-125.5, 0]
  const std::int32_t n = std::int32_t(t - 0.5f);  // ceil(t - 1/2), truncation toward zero
  const float f = t - float(n);                   // in (-1/2, 1/2]
  float p = 1.546144485e-04f;
  p = p * f + 1.340042800e-03f;
  p = p * f + 9.618056938e-03f;
  p = p * f + 5.550327152e-02f;
  p = p * f + 2.402265072e-01f;
  p = p * f + 6.931471825e-01f;
  p = p * f + 1.0f;
  const std::int32_t bits = (n + 127) << 23;  // 2^n, a normal float for n >= -126
  return p * __builtin_bit_cast(float, bits);
}

inline double exp_nonpositive(double x) { return std::exp(x); }

}  // namespace spikegs::raster
