// The rasterizer's numerical constants: forward, backward and Python (spikegs._C.constants) read
// them from here. See docs/rasterizer.md.
#pragma once

#include <cmath>

namespace spikegs::raster {
constexpr int kTileSize = 16;               // tiles are kTileSize x kTileSize pixels
constexpr double kAlphaMax = 0.99;          // alpha = min(kAlphaMax, o * G)
constexpr double kAlphaMin = 1.0 / 255.0;   // a (pixel, Gaussian) pair with alpha below is skipped
constexpr double kTransmittanceMin = 1e-4;  // a pixel stops before T would fall below this
constexpr double kDilation = 0.3;           // low-pass filter added to the 2D covariance (px^2)
constexpr double kClampMargin = 0.3;        // frustum margin for the Jacobian, in half-FOV units
constexpr double kDefaultNear = 0.01;
constexpr double kDefaultFar = 1e10;
constexpr int kMaxShDegree = 3;

// kAlphaMax in T, rounded down where T's nearest value lies above it (float's 0.99000001): two
// clamped Gaussians leave T = (1 - alpha)^2, not below kTransmittanceMin, as in exact arithmetic,
// and the second counts (float's nearest value stopped the pixel before it)
template <typename T>
T alpha_max() {
  const T nearest = T(kAlphaMax);
  return double(nearest) > kAlphaMax ? std::nextafter(nearest, T(0)) : nearest;
}
}  // namespace spikegs::raster
