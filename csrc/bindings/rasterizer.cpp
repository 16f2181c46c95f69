// Binding of the rasterizer: float32 and float64 variants, numpy arrays in and out (zero copy for
// C-contiguous arrays of the right dtype), the GIL released while the core runs.
#include "core/rasterizer.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "bindings/register.hpp"

namespace py = pybind11;
namespace sr = spikegs::raster;

namespace spikegs {
namespace {

template <typename T>
using Array = py::array_t<T, py::array::c_style | py::array::forcecast>;

// The forward's state, kept by Python between forward and backward.
template <typename T>
struct RasterContext {
  sr::Camera<T> cam;
  sr::RasterState<T> state;
  int sh_degree, sh_coeffs, channels;
};

template <typename T>
sr::GaussianParams<T> params_of(const Array<T>& means, const Array<T>& quats,
                                const Array<T>& scales, const Array<T>& opacities,
                                const Array<T>& colors, int sh_degree, int sh_coeffs,
                                int channels) {
  sr::GaussianParams<T> p{means.data(), quats.data(), scales.data(), opacities.data(),
                          colors.data()};
  p.n = means.shape(0);
  p.channels = channels;
  p.sh_degree = sh_degree;
  p.sh_coeffs = sh_coeffs;
  const py::ssize_t n = p.n;
  // the core trusts these (spikegs.rasterize checks them with messages of its own): out of
  // bounds reads otherwise
  if (sh_degree < -1 || sh_degree > sr::kMaxShDegree || channels < 1 ||
      (sh_degree >= 0 && sh_coeffs < (sh_degree + 1) * (sh_degree + 1)))
    throw py::value_error(
        "rasterize: sh_degree in -1..3 (with sh_coeffs >= (degree + 1)^2) and "
        "channels >= 1 expected");
  if (means.size() != 3 * n || quats.size() != 4 * n || scales.size() != 3 * n ||
      opacities.size() != n || colors.size() != n * p.color_stride())
    throw py::value_error("rasterize: input sizes do not match N = " + std::to_string(n));
  if (n > std::numeric_limits<std::int32_t>::max())  // the binning's depth ranks are 32-bit
    throw py::value_error("rasterize: at most 2^31 - 1 Gaussians");
  return p;
}

constexpr int kMaxImageSize = 1 << 20;  // width and height: tile and pixel indices are 32-bit

// std::bad_alloc saying what ran out of memory: pybind11 raises MemoryError with its what(),
// which was a bare "std::bad_alloc". The message is shared, so that copies cannot throw.
class OutOfMemory : public std::bad_alloc {
 public:
  explicit OutOfMemory(std::string message)
      : message_(std::make_shared<const std::string>(std::move(message))) {}
  const char* what() const noexcept override { return message_->c_str(); }

 private:
  std::shared_ptr<const std::string> message_;
};

// run(), an out-of-memory error in it named with the work that needed the memory: the
// Gaussians, pixels, channels and, once binned, the (tile, Gaussian) pairs.
template <typename T, typename Run>
void naming_memory(const char* stage, const sr::RasterState<T>& state, std::int64_t gaussians,
                   const sr::Camera<T>& cam, int channels, Run&& run) {
  try {
    run();
  } catch (const std::bad_alloc&) {
    std::ostringstream os;
    os << "rasterize " << stage << ": out of memory with " << gaussians << " Gaussians, "
       << cam.width << "x" << cam.height << " pixels, " << channels << " channel(s)";
    const std::vector<std::int64_t>& begin = state.bins.rank_begin;
    if (!begin.empty() && begin.size() == state.bins.order.size() + 1)
      os << " and " << begin.back() << " (tile, Gaussian) pairs";
    os << "; fewer or smaller Gaussians, fewer channels or a smaller image need less";
    throw OutOfMemory(os.str());
  }
}

template <typename T>
void check_background(const std::optional<Array<T>>& background, int channels) {
  if (background && background->size() != channels)
    throw py::value_error("rasterize: background must have C entries");
}

template <typename T>
py::tuple forward(const Array<T>& means, const Array<T>& quats, const Array<T>& scales,
                  const Array<T>& opacities, const Array<T>& colors, const Array<T>& viewmat,
                  const Array<T>& K, int width, int height, int sh_degree, int sh_coeffs,
                  int channels, std::optional<Array<T>> background, T near_plane, T far_plane,
                  bool antialiased, T dilation) {
  auto ctx = std::make_shared<RasterContext<T>>();
  ctx->sh_degree = sh_degree, ctx->sh_coeffs = sh_coeffs, ctx->channels = channels;
  sr::Camera<T>& cam = ctx->cam;
  if (viewmat.size() != 16 || K.size() != 9)
    throw py::value_error("rasterize: viewmat must be 4x4, K 3x3");
  std::copy(viewmat.data(), viewmat.data() + 16, cam.viewmat);
  cam.fx = K.data()[0], cam.fy = K.data()[4], cam.cx = K.data()[2], cam.cy = K.data()[5];
  cam.width = width, cam.height = height, cam.near_plane = near_plane, cam.far_plane = far_plane;
  cam.antialiased = antialiased, cam.dilation = dilation;
  // what the core assumes (spikegs.rasterize checks each with its own message): depths sorted by
  // their bits need 0 < near; the alpha cut-off needs opacities <= 1; tile counts fit an int
  if (!(cam.fx > 0 && cam.fy > 0 && std::isfinite(cam.fx) && std::isfinite(cam.fy)))
    throw py::value_error("rasterize: focal lengths fx, fy > 0 expected");
  if (!(T(0) < cam.near_plane && cam.near_plane < cam.far_plane))
    throw py::value_error("rasterize: 0 < near < far expected");
  if (!(cam.dilation >= T(sr::kMinDilation) && cam.dilation <= T(sr::kMaxDilation)))
    throw py::value_error("rasterize: a dilation in min_dilation..max_dilation px^2 expected");
  if (width < 1 || height < 1 || width > kMaxImageSize || height > kMaxImageSize)
    throw py::value_error("rasterize: width and height in 1..2^20 expected");
  const sr::GaussianParams<T> p =
      params_of(means, quats, scales, opacities, colors, sh_degree, sh_coeffs, channels);
  auto outside = [](T o) { return std::isfinite(o) && (o < T(0) || o > T(1)); };
  if (std::any_of(p.opacities, p.opacities + p.n, outside))
    throw py::value_error("rasterize: opacities in [0, 1] expected (NaN and inf culled)");
  check_background(background, channels);
  const T* bg = background ? background->data() : nullptr;

  Array<T> image({py::ssize_t(height), py::ssize_t(width), py::ssize_t(channels)});
  Array<T> alpha({py::ssize_t(height), py::ssize_t(width)});
  {
    py::gil_scoped_release release;
    naming_memory("forward", ctx->state, p.n, cam, channels, [&] {
      sr::rasterize_forward(p, cam, bg, image.mutable_data(), alpha.mutable_data(), ctx->state);
    });
  }
  const py::ssize_t n = p.n;
  const auto& proj = ctx->state.proj;
  Array<std::int32_t> radii(n);
  Array<T> means2d({n, py::ssize_t(2)}), depths(n);
  std::copy(proj.radius.begin(), proj.radius.end(), radii.mutable_data());
  std::copy(proj.mean2d.begin(), proj.mean2d.end(), means2d.mutable_data());
  std::copy(proj.depth.begin(), proj.depth.end(), depths.mutable_data());
  return py::make_tuple(image, alpha, radii, means2d, depths, ctx);
}

template <typename T>
py::tuple backward(const RasterContext<T>& ctx, const Array<T>& means, const Array<T>& quats,
                   const Array<T>& scales, const Array<T>& opacities, const Array<T>& colors,
                   std::optional<Array<T>> background, const Array<T>& grad_image,
                   std::optional<Array<T>> grad_alpha, std::optional<Array<T>> grad_means2d,
                   std::optional<Array<T>> grad_depths) {
  const sr::GaussianParams<T> p = params_of(means, quats, scales, opacities, colors, ctx.sh_degree,
                                            ctx.sh_coeffs, ctx.channels);
  if (std::int64_t(ctx.state.proj.radius.size()) != p.n)
    throw py::value_error("rasterize backward: the forward's context holds " +
                          std::to_string(ctx.state.proj.radius.size()) + " Gaussians, not " +
                          std::to_string(p.n));
  const py::ssize_t pixels = py::ssize_t(ctx.cam.width) * ctx.cam.height;
  if (grad_image.size() != pixels * ctx.channels || (grad_alpha && grad_alpha->size() != pixels))
    throw py::value_error("rasterize backward: gradient shapes do not match the image");
  if ((grad_means2d && grad_means2d->size() != 2 * p.n) ||
      (grad_depths && grad_depths->size() != p.n))
    throw py::value_error("rasterize backward: gradient shapes do not match the Gaussians");
  check_background(background, ctx.channels);  // the backward reads C entries too
  auto zeros_like = [](const Array<T>& a) {
    Array<T> z(std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()));
    std::fill(z.mutable_data(), z.mutable_data() + z.size(), T(0));
    return z;
  };
  Array<T> dmeans = zeros_like(means), dquats = zeros_like(quats), dscales = zeros_like(scales);
  Array<T> dopac = zeros_like(opacities), dcolors = zeros_like(colors);
  Array<T> dviewmat({4, 4}), dbackground(py::ssize_t(ctx.channels)),
      dmeans2d({p.n, py::ssize_t(2)}), dmeans2d_abs({p.n, py::ssize_t(2)});
  std::fill(dviewmat.mutable_data(), dviewmat.mutable_data() + 16, T(0));
  sr::ParamGrads<T> g{dmeans.mutable_data(), dquats.mutable_data(),  dscales.mutable_data(),
                      dopac.mutable_data(),  dcolors.mutable_data(), dviewmat.mutable_data()};
  {
    py::gil_scoped_release release;
    const sr::OutputGrads<T> dout{grad_image.data(), grad_alpha ? grad_alpha->data() : nullptr,
                                  grad_means2d ? grad_means2d->data() : nullptr,
                                  grad_depths ? grad_depths->data() : nullptr};
    naming_memory("backward", ctx.state, p.n, ctx.cam, ctx.channels, [&] {
      sr::rasterize_backward(p, ctx.cam, background ? background->data() : nullptr, ctx.state, dout,
                             g, dbackground.mutable_data(), dmeans2d.mutable_data(),
                             dmeans2d_abs.mutable_data());
    });
  }
  return py::make_tuple(dmeans, dquats, dscales, dopac, dcolors, dviewmat, dbackground, dmeans2d,
                        dmeans2d_abs);
}

template <typename T>
void bind_variant(py::module_& m, const std::string& suffix) {
  using Ctx = RasterContext<T>;
  py::class_<Ctx, std::shared_ptr<Ctx>>(m, ("RasterContext_" + suffix).c_str())
      .def_property_readonly(
          "pairs", [](const Ctx& c) { return c.state.composite.pairs; },
          "(pixel, Gaussian) pairs evaluated by the forward");
  m.def(("rasterize_forward_" + suffix).c_str(), &forward<T>, py::arg("means"), py::arg("quats"),
        py::arg("scales"), py::arg("opacities"), py::arg("colors"), py::arg("viewmat"),
        py::arg("K"), py::arg("width"), py::arg("height"), py::arg("sh_degree"),
        py::arg("sh_coeffs"), py::arg("channels"), py::arg("background"), py::arg("near"),
        py::arg("far"), py::arg("antialiased") = false, py::arg("dilation") = T(sr::kDilation),
        "-> (image [H,W,C], alpha [H,W], radii [N], means2d [N,2], depths [N], context)");
  m.def(("rasterize_backward_" + suffix).c_str(), &backward<T>, py::arg("context"),
        py::arg("means"), py::arg("quats"), py::arg("scales"), py::arg("opacities"),
        py::arg("colors"), py::arg("background"), py::arg("grad_image"), py::arg("grad_alpha"),
        py::arg("grad_means2d"), py::arg("grad_depths"),
        "-> gradients (means, quats, scales, opacities, colors, viewmat, background, means2d, "
        "means2d_abs: the compositing's per-pixel shares of means2d's summed in |.|)");
}

}  // namespace

void bind_rasterizer(py::module_& m) {
  bind_variant<float>(m, "float32");
  bind_variant<double>(m, "float64");
  py::dict constants;
  constants["tile_size"] = sr::kTileSize;
  constants["alpha_max"] = sr::kAlphaMax;
  constants["alpha_min"] = sr::kAlphaMin;
  constants["transmittance_min"] = sr::kTransmittanceMin;
  constants["dilation"] = sr::kDilation;
  constants["min_dilation"] = sr::kMinDilation;
  constants["max_dilation"] = sr::kMaxDilation;
  constants["max_mean2d"] = sr::kMaxMean2d;
  constants["clamp_margin"] = sr::kClampMargin;
  constants["near"] = sr::kDefaultNear;
  constants["far"] = sr::kDefaultFar;
  constants["max_sh_degree"] = sr::kMaxShDegree;
  constants["max_image_size"] = kMaxImageSize;
  m.attr("constants") = constants;
}

}  // namespace spikegs
