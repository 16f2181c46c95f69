#include "core/rasterizer.hpp"

#include <algorithm>

namespace spikegs::raster {

template <typename T>
void rasterize_forward(const GaussianParams<T>& params, const Camera<T>& cam, const T* background,
                       T* image, T* alpha, RasterState<T>& state) {
  project_forward(params, cam, state.proj);
  bin_tiles(state.proj, cam, state.bins);
  composite_forward(state.proj, state.bins, cam.width, cam.height, params.channels, background,
                    image, alpha, state.composite);
}

template <typename T>
void rasterize_backward(const GaussianParams<T>& params, const Camera<T>& cam, const T* background,
                        const RasterState<T>& state, const OutputGrads<T>& dout,
                        ParamGrads<T>& grads, T* grad_background, T* grad_mean2d,
                        T* grad_mean2d_abs) {
  ProjectedGrads<T> dproj;
  composite_backward(state.proj, state.bins, cam.width, cam.height, params.channels, background,
                     state.composite, dout.image, dout.alpha, dproj, grad_background);
  if (dout.mean2d)  // a culled Gaussian's outputs are constants (0)
    for (std::int64_t i = 0; i < params.n; ++i)
      if (state.proj.radius[i] > 0)
        for (int k = 0; k < 2; ++k) dproj.mean2d[2 * i + k] += dout.mean2d[2 * i + k];
  if (dout.depth) dproj.depth.assign(dout.depth, dout.depth + params.n);
  if (grad_mean2d) std::copy(dproj.mean2d.begin(), dproj.mean2d.end(), grad_mean2d);
  if (grad_mean2d_abs) std::copy(dproj.mean2d_abs.begin(), dproj.mean2d_abs.end(), grad_mean2d_abs);
  project_backward(params, cam, state.proj, dproj, grads);
}

template void rasterize_forward<float>(const GaussianParams<float>&, const Camera<float>&,
                                       const float*, float*, float*, RasterState<float>&);
template void rasterize_forward<double>(const GaussianParams<double>&, const Camera<double>&,
                                        const double*, double*, double*, RasterState<double>&);
template void rasterize_backward<float>(const GaussianParams<float>&, const Camera<float>&,
                                        const float*, const RasterState<float>&,
                                        const OutputGrads<float>&, ParamGrads<float>&, float*,
                                        float*, float*);
template void rasterize_backward<double>(const GaussianParams<double>&, const Camera<double>&,
                                         const double*, const RasterState<double>&,
                                         const OutputGrads<double>&, ParamGrads<double>&, double*,
                                         double*, double*);

}  // namespace spikegs::raster
