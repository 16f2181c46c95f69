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

// Adds the input gradients to `grads` (zero-initialised arrays); `grad_alpha`, `grad_background`
// and `grad_mean2d` ([N, 2], the screen-space gradient used for densification) may be null.
template <typename T>
void rasterize_backward(const GaussianParams<T>& params, const Camera<T>& cam, const T* background,
                        const RasterState<T>& state, const T* grad_image, const T* grad_alpha,
                        ParamGrads<T>& grads, T* grad_background, T* grad_mean2d);

}  // namespace spikegs::raster
