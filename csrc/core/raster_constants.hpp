// The rasterizer's numerical constants: forward, backward and Python (spikegs._C.constants) read
// them from here. See docs/rasterizer.md.
#pragma once

#include <cmath>
#include <limits>

namespace spikegs::raster {
constexpr int kTileSize = 16;               // tiles are kTileSize x kTileSize pixels
constexpr double kAlphaMax = 0.99;          // alpha = min(kAlphaMax, o * G)
constexpr double kAlphaMin = 1.0 / 255.0;   // a (pixel, Gaussian) pair with alpha below is skipped
constexpr double kTransmittanceMin = 1e-4;  // a pixel stops before T would fall below this
constexpr double kDilation = 0.3;           // low-pass filter added to the 2D covariance (px^2)
constexpr double kMinDilation = 0.01;       // the range a caller may set it in (Camera::dilation):
constexpr double kMaxDilation = 10.0;       // conics stay below 1 / kMinDilation
constexpr double kClampMargin = 0.3;        // frustum margin for the Jacobian, in half-FOV units
// a splat whose 2D mean lies farther than this from the image origin, in x or y (px), is culled:
// float32's power A dx² (A <= 1 / kMinDilation) and the backward's sums of dx² over up to 2^40
// pixels stay finite within it (a NaN power reached exp's integer conversion: undefined)
constexpr double kMaxMean2d = 1099511627776.0;  // 2^40
constexpr double kDefaultNear = 0.01;
constexpr double kDefaultFar = 1e10;
constexpr int kMaxShDegree = 3;

// 2 ln(o / kAlphaMin) for opacity o: alpha = o·exp(-d^T conic d / 2) >= 1/255 inside the ellipse
// d^T conic d <= this level (the projection's radius and box, the compositing's rows).
template <typename T>
inline T support_level(T opacity) {
  return T(2) * std::log(T(1.0 / kAlphaMin) * opacity);
}

// kAlphaMax in T, rounded down where T's nearest value lies above it (float's 0.99000001): two
// clamped Gaussians leave T = (1 - alpha)^2, not below kTransmittanceMin, as in exact arithmetic,
// and the second counts (float's nearest value stopped the pixel before it). Called where used: a
// local copy, which std::min takes by reference, was shared into the OpenMP regions and halved
// the compositing loops' speed. One ulp below a value in [0.5, 1) is epsilon / 2.
template <typename T>
constexpr T alpha_max() {
  constexpr T nearest = T(kAlphaMax);
  return double(nearest) > kAlphaMax ? nearest - std::numeric_limits<T>::epsilon() / 2 : nearest;
}
static_assert(alpha_max<float>() < 0.99f && double(alpha_max<float>()) < kAlphaMax &&
                  double(alpha_max<float>()) > kAlphaMax - 1e-7,
              "alpha_max<float>: the float just below 0.99");
}  // namespace spikegs::raster
