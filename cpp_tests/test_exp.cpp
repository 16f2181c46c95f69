// The compositing loops' inline exp (core/exp_nonpositive.hpp) against double std::exp.
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <vector>

#include "core/exp_nonpositive.hpp"
#include "harness.hpp"

using spikegs::raster::exp_nonpositive;

namespace {
double relative_error(float x) {
  return std::fabs(double(exp_nonpositive(x)) / std::exp(double(x)) - 1);
}

// Arguments in [lo, hi]: an even sweep, and the points where the integer part of x / ln 2 steps
// (the polynomial's argument jumps from +1/2 to -1/2 there) with their float neighbours.
std::vector<float> arguments(float lo, float hi) {
  std::vector<float> xs;
  constexpr int kSweep = 1000000;
  for (int i = 0; i <= kSweep; ++i) xs.push_back(hi + (lo - hi) * float(i) / kSweep);
  for (int n = 0; -(n + 0.5) * std::log(2.0) >= lo; ++n) {
    const float step = float(-(n + 0.5) * std::log(2.0));
    float x = std::nextafter(std::nextafter(step, 0.f), 0.f);
    for (int k = 0; k < 5; ++k, x = std::nextafter(x, lo)) xs.push_back(x);
  }
  return xs;
}
}  // namespace

TEST_CASE(exp_nonpositive_matches_std_exp) {
  // the compositing's range, [-20, 0]: about the rounding of x / ln 2 to float (|x| / ln 2 ulp)
  double worst = 0;
  for (float x : arguments(-20.f, 0.f)) worst = std::max(worst, relative_error(x));
  CHECK(worst < 1.5e-6, "relative error ", worst, " on [-20, 0]");
  // where alpha >= 1/255 can come out (x >= -ln 255): within a few float ulps
  worst = 0;
  for (float x : arguments(-5.6f, 0.f)) worst = std::max(worst, relative_error(x));
  CHECK(worst < 5e-7, "relative error ", worst, " on [-5.6, 0]");
  // the whole range it is defined on: 2^n stays a normal float
  worst = 0;
  for (float x : arguments(-87.f, -20.f)) worst = std::max(worst, relative_error(x));
  CHECK(worst < 6e-6, "relative error ", worst, " on [-87, -20]");
}

TEST_CASE(exp_nonpositive_exact_and_monotone_near_zero) {
  CHECK(exp_nonpositive(0.f) == 1.f, "exp(0) = ", exp_nonpositive(0.f));
  CHECK(exp_nonpositive(-0.f) == 1.f, "exp(-0) = ", exp_nonpositive(-0.f));
  for (float x : {-FLT_MIN, -1e-30f, -1e-8f}) CHECK(exp_nonpositive(x) == 1.f, "exp(", x, ")");
  // no step down at a change of the integer part larger than the function's own slope allows
  float previous = exp_nonpositive(0.f);
  for (float x = -1e-3f; x >= -20.f; x -= 1e-3f) {
    const float now = exp_nonpositive(x);
    CHECK(now <= previous * (1 + 2e-6f), "not monotone at ", x, ": ", now, " after ", previous);
    previous = now;
  }
  CHECK(exp_nonpositive(-87.f) > 0.f && exp_nonpositive(-87.f) < 2e-38f, "exp(-87) underflows");
}
