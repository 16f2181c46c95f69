// Front-to-back alpha compositing of binned splats, and its vector-Jacobian product.
#pragma once
#include <cstdint>
#include <vector>

#include "core/raster_types.hpp"
#include "core/tile_binning.hpp"

namespace spikegs::raster {

// What the backward needs from the forward, per pixel.
template <typename T>
struct CompositeState {
  std::vector<T> final_T;  // [H, W] transmittance left after the last contributor
  std::vector<std::int32_t>
      last;                // [H, W] position in the tile's list of the last contributor, -1: none
  std::int64_t pairs = 0;  // (pixel, Gaussian) pairs evaluated
  std::vector<T> splats;   // [visible, 11 + C] the splats as the forward gathered them, in depth
                           // order; the backward reads them (both then take the same rows)
};

// image [H, W, C] = sum alpha T c + T_final background; alpha [H, W] = 1 - T_final.
template <typename T>
void composite_forward(const Projected<T>& proj, const TileBins& bins, int width, int height,
                       int channels, const T* background, T* image, T* alpha,
                       CompositeState<T>& state);

// Gradients of the projected quantities (indexed by Gaussian, zero-initialised by the callee) and
// of the background, given those of image and alpha.
template <typename T>
void composite_backward(const Projected<T>& proj, const TileBins& bins, int width, int height,
                        int channels, const T* background, const CompositeState<T>& state,
                        const T* grad_image, const T* grad_alpha, ProjectedGrads<T>& grads,
                        T* grad_background);

}  // namespace spikegs::raster
