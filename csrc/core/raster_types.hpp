// Plain data exchanged between the rasterizer's stages. Arrays are flat, row-major, owned by the
// caller unless they are std::vector members.
#pragma once
#include <cstdint>
#include <vector>

#include "core/raster_constants.hpp"

namespace spikegs::raster {

template <typename T>
struct Camera {
  T viewmat[16];  // world-to-camera, row-major 4x4 (OpenCV axes)
  T fx, fy, cx, cy;
  int width, height;
  T near_plane, far_plane;
  // the low-pass filter added to each 2D covariance's diagonal (px^2), kMinDilation..kMaxDilation
  // (3DGS's 0.3, Mip-Splatting's 2D filter 0.1)
  T dilation = T(kDilation);
  // the antialiased variant of the 2D filter (Mip-Splatting's, gsplat's "antialiased" mode): each
  // opacity scaled by sqrt(det(cov2d) / det(cov2d + dilation)), so that dilating a splat keeps
  // its integral instead of adding to it
  bool antialiased = false;
  int tiles_x() const { return (width + kTileSize - 1) / kTileSize; }
  int tiles_y() const { return (height + kTileSize - 1) / kTileSize; }
};

template <typename T>
struct GaussianParams {
  const T* means;      // [N, 3]
  const T* quats;      // [N, 4] (w, x, y, z), any norm
  const T* scales;     // [N, 3]
  const T* opacities;  // [N]
  const T* colors;     // [N, C] direct, or [N, K, C] SH coefficients
  std::int64_t n = 0;
  int channels = 1;    // C
  int sh_degree = -1;  // -1: direct colours
  int sh_coeffs = 1;   // K, the stride of SH coefficients (>= (sh_degree + 1)^2)
  std::int64_t color_stride() const {
    return sh_degree < 0 ? channels : std::int64_t(sh_coeffs) * channels;
  }
};

// Per-Gaussian outputs of the projection; radius 0 marks a culled Gaussian.
template <typename T>
struct Projected {
  std::vector<T> mean2d;             // [N, 2]
  std::vector<T> conic;              // [N, 3] (A, B, C) of the inverse 2D covariance
  std::vector<T> depth;              // [N]
  std::vector<T> opacity;            // [N]
  std::vector<T> color;              // [N, C]
  std::vector<std::int32_t> radius;  // [N] pixels, 0 = culled
  std::vector<T> extent;  // [N, 2] x, y half-widths of the region where alpha >= 1/255 (+1 px)
  std::vector<std::int32_t> tile_rect;  // [N, 4] tile range x0, y0, x1, y1 (half-open; non-empty
                                        // and on the grid where radius > 0)
};

// Gradients with respect to the projected quantities, indexed by Gaussian.
template <typename T>
struct ProjectedGrads {
  std::vector<T> mean2d;      // [N, 2]
  std::vector<T> conic;       // [N, 3]
  std::vector<T> opacity;     // [N]
  std::vector<T> color;       // [N, C]
  std::vector<T> depth;       // [N], or empty: no gradient of the depths
  std::vector<T> mean2d_abs;  // [N, 2] the compositing's per-pixel shares of mean2d, in |.|
};

// Gradients with respect to the inputs; pointers to caller-owned, zero-initialised arrays.
template <typename T>
struct ParamGrads {
  T* means;      // [N, 3]
  T* quats;      // [N, 4]
  T* scales;     // [N, 3]
  T* opacities;  // [N]
  T* colors;     // same shape as GaussianParams::colors
  T* viewmat;    // [4, 4]
};

}  // namespace spikegs::raster
