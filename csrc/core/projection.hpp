// Projection of 3D Gaussians to screen-space splats (EWA), and its vector-Jacobian product.
#pragma once
#include "core/raster_types.hpp"

namespace spikegs::raster {

// Fills `out` (resized to N) with 2D means, conics, depths, opacities, colours, radii and tile
// ranges; culled Gaussians get radius 0. Parallel over Gaussians.
template <typename T>
void project_forward(const GaussianParams<T>& params, const Camera<T>& cam, Projected<T>& out);

// Adds the gradients of the inputs given those of the projected quantities. Culled Gaussians get
// nothing. `grads.viewmat` receives the world-to-camera gradient (reduced over threads).
template <typename T>
void project_backward(const GaussianParams<T>& params, const Camera<T>& cam,
                      const Projected<T>& proj, const ProjectedGrads<T>& dproj,
                      ParamGrads<T>& grads);

}  // namespace spikegs::raster
