// The whole rasterizer: projection, tile binning and compositing, forward and backward.
#pragma once
#include "core/composite.hpp"
#include "core/projection.hpp"
#include "core/tile_binning.hpp"

namespace spikegs::raster {

// Everything the forward leaves for the backward.
template <typename T>
struct RasterState {
  Projected<T> proj;
  TileBins bins;
  CompositeState<T> composite;
};

// image [H, W, C], alpha [H, W]; `background` [C] may be null (black).
template <typename T>
void rasterize_forward(const GaussianParams<T>& params, const Camera<T>& cam, const T* background,
                       T* image, T* alpha, RasterState<T>& state);

// Gradients of a loss with respect to the forward's outputs; all but `image` may be null.
template <typename T>
struct OutputGrads {
  const T* image;             // [H, W, C]
  const T* alpha = nullptr;   // [H, W]
  const T* mean2d = nullptr;  // [N, 2]
  const T* depth = nullptr;   // [N]
};

// Adds the input gradients to `grads` (zero-initialised arrays). Optional (may be null):
// `grad_background`; `grad_mean2d` [N, 2], the screen-space gradient used for densification (of
// the 2D means' every use, the compositing's and `dout.mean2d`'s); `grad_mean2d_abs` [N, 2], the
// compositing's per-pixel shares of it summed in absolute value (AbsGS's densification signal).
template <typename T>
void rasterize_backward(const GaussianParams<T>& params, const Camera<T>& cam, const T* background,
                        const RasterState<T>& state, const OutputGrads<T>& dout,
                        ParamGrads<T>& grads, T* grad_background, T* grad_mean2d,
                        T* grad_mean2d_abs);

}  // namespace spikegs::raster
