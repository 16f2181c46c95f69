// The rasterizer's stiff and extreme cases (degenerate, huge, tiny, stacked, non-finite inputs):
// each renders in float and double, and checks finite outputs and gradients, zero gradient for
// culled Gaussians, and float-vs-double agreement.
#include <algorithm>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <tuple>

#include "harness.hpp"
#include "raster_scene.hpp"

using namespace test;

namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();

template <typename T>
bool finite(const std::vector<T>& v) {
  return spikegs::all_finite(v.data(), long(v.size()));
}

// Renders `s` in double and float with a random upstream gradient; checks finiteness and returns
// the double gradients. Prints the float-vs-double image error.
struct Outcome {
  Render<double> render;
  Grads<double> grads;
  double float_error;
};

Outcome run_filter(const Scene<double>& s, const char* label) {
  Render<double> r = render(s);
  check_bins(r.state, s.cam, label);  // before the backward, which indexes by the bins
  const auto gi = random_weights(r.image.size(), 7), ga = random_weights(r.alpha.size(), 8);
  Grads<double> g = backward(s, r, gi, ga);
  const Scene<float> sf = s.cast<float>();
  const Render<float> rf = render(sf);
  check_bins(rf.state, sf.cam, label);
  const Grads<float> gf = backward(sf, rf, std::vector<float>(gi.begin(), gi.end()),
                                   std::vector<float>(ga.begin(), ga.end()));
  CHECK(finite(r.image) && finite(r.alpha), label, ": non-finite double output");
  CHECK(finite(rf.image) && finite(rf.alpha), label, ": non-finite float output");
  CHECK(g.finite(), label, ": non-finite double gradient");
  CHECK(gf.finite(), label, ": non-finite float gradient");
  double err = 0;
  for (std::size_t k = 0; k < r.image.size(); ++k)
    err = std::max(err, std::abs(r.image[k] - double(rf.image[k])));
  for (std::size_t k = 0; k < r.alpha.size(); ++k)
    err = std::max(err, std::abs(r.alpha[k] - double(rf.alpha[k])));
  std::printf("  %s: %zu of %lld visible, max |float - double| = %.3g\n", label,
              r.state.bins.order.size(), (long long)s.n, err);
  return {std::move(r), std::move(g), err};
}

// run_filter with the plain 2D filter, whose outcome it returns, with the antialiased one (each
// opacity scaled by sqrt(det cov2d / det(cov2d + dilation))), and at the dilation's two ends (the
// least: conics up to 100 px^-2), finite alike.
Outcome run(const Scene<double>& s, const char* label) {
  for (const auto& [antialiased, dilation, name] :
       {std::tuple{true, kDilation, ", antialiased"},
        std::tuple{false, kMinDilation, ", least dilation"},
        std::tuple{true, kMinDilation, ", antialiased, least dilation"},
        std::tuple{true, kMaxDilation, ", antialiased, most dilation"}}) {
    Scene<double> filtered = s;
    filtered.cam.antialiased = antialiased, filtered.cam.dilation = dilation;
    run_filter(filtered, (std::string(label) + name).c_str());
  }
  return run_filter(s, label);
}

// Gradient entries of Gaussian i, all of which must be zero when it is culled.
bool zero_grads(const Scene<double>& s, const Grads<double>& g, std::int64_t i) {
  auto zero = [](const std::vector<double>& v, std::int64_t from, std::int64_t count) {
    for (std::int64_t k = from; k < from + count; ++k)
      if (v[k] != 0) return false;
    return true;
  };
  const std::int64_t cs = s.params().color_stride();
  return zero(g.means, 3 * i, 3) && zero(g.quats, 4 * i, 4) && zero(g.scales, 3 * i, 3) &&
         zero(g.opacities, i, 1) && zero(g.colors, cs * i, cs) && zero(g.mean2d, 2 * i, 2);
}

// `s` with Gaussians [from, s.n) removed.
Scene<double> truncated(Scene<double> s, std::int64_t keep) {
  const std::int64_t cs = s.params().color_stride();
  s.n = keep;
  s.means.resize(3 * keep), s.quats.resize(4 * keep), s.scales.resize(3 * keep);
  s.opacities.resize(keep), s.colors.resize(cs * keep);
  return s;
}

// The appended Gaussians [keep, n) must be culled: zero gradients and the image of the others.
void check_culled_tail(const Scene<double>& s, std::int64_t keep, const char* label) {
  const Outcome o = run(s, label);
  for (std::int64_t i = keep; i < s.n; ++i) {
    CHECK(o.render.state.proj.radius[i] == 0, label, ": Gaussian ", i, " not culled");
    CHECK(zero_grads(s, o.grads, i), label, ": culled Gaussian ", i, " has a gradient");
  }
  const Render<double> base = render(truncated(s, keep));
  CHECK(base.image == o.render.image && base.alpha == o.render.alpha, label,
        ": culled Gaussians changed the image");
}

}  // namespace

TEST_CASE(scales_span_nine_decades) {
  Scene<double> s = random_scene(1, 40, 64, 48, 3, -1);
  for (std::int64_t i = 0; i < s.n; ++i)
    for (int k = 0; k < 3; ++k)
      s.scales[3 * i + k] = std::pow(10.0, -6.0 + 9.0 * ((i * 3 + k) % 10) / 9.0);
  const Outcome o = run(s, "scales 1e-6..1e3");
  CHECK(o.float_error < 1e-3, "float error ", o.float_error);
}

TEST_CASE(covariance_condition_1e8) {
  Scene<double> s = random_scene(2, 30, 64, 48, 3, -1);
  for (std::int64_t i = 0; i < s.n; ++i)
    s.scales[3 * i] = 0.5, s.scales[3 * i + 1] = s.scales[3 * i + 2] = 0.5e-4;
  const Outcome o = run(s, "condition 1e8");
  CHECK(o.float_error < 1e-3, "float error ", o.float_error);
}

TEST_CASE(near_plane_and_behind_camera) {
  Scene<double> s = random_scene(3, 10, 33, 17, 3, 1);
  // identity camera; means straddling the near plane (0.01) and behind the camera
  for (int k = 0; k < 16; ++k) s.cam.viewmat[k] = (k % 5 == 0) ? 1 : 0;
  const double zs[] = {-2.0, -0.5, -0.01, 0.0, 0.005, 0.01, 0.0100001, 0.05, 0.5, 2.0};
  for (std::int64_t i = 0; i < s.n; ++i) {
    s.means[3 * i] = 0.01 * (i - 5), s.means[3 * i + 1] = 0.005 * i, s.means[3 * i + 2] = zs[i];
    for (int k = 0; k < 3; ++k) s.scales[3 * i + k] = 0.3;  // straddles z = near
  }
  const Outcome o = run(s, "near plane");
  for (std::int64_t i = 0; i < s.n; ++i) {
    const bool in_front = zs[i] > s.cam.near_plane;
    CHECK(in_front || o.render.state.proj.radius[i] == 0, "Gaussian at z=", zs[i], " not culled");
    CHECK(in_front || zero_grads(s, o.grads, i), "Gaussian at z=", zs[i], " has a gradient");
  }
  CHECK(o.float_error < 1e-3, "float error ", o.float_error);
}

TEST_CASE(opacity_logits_plus_minus_30) {
  Scene<double> s = random_scene(4, 20, 33, 17, 1, -1);
  for (std::int64_t i = 0; i < s.n; ++i) s.opacities[i] = 1 / (1 + std::exp(i % 2 ? 30.0 : -30.0));
  const Outcome o = run(s, "opacity logits +-30");
  for (std::int64_t i = 1; i < s.n; i += 2)
    CHECK(zero_grads(s, o.grads, i), "transparent Gaussian ", i, " has a gradient");
  CHECK(o.float_error < 1e-3, "float error ", o.float_error);
}

TEST_CASE(hundreds_stacked_on_one_pixel) {
  Scene<double> s = random_scene(5, 400, 13, 9, 3, -1);
  for (std::int64_t i = 0; i < s.n; ++i) {
    s.means[3 * i] = 0, s.means[3 * i + 1] = 0, s.means[3 * i + 2] = 2 + 1e-3 * i;
    for (int k = 0; k < 3; ++k) s.scales[3 * i + k] = 0.05;
    s.opacities[i] = 0.9;
  }
  for (int k = 0; k < 16; ++k) s.cam.viewmat[k] = (k % 5 == 0) ? 1 : 0;
  const Outcome o = run(s, "400 stacked");
  const auto& a = o.render.alpha;
  const double peak = *std::max_element(a.begin(), a.end());
  CHECK(peak > 1 - 1e-3 && peak <= 1 - 0.5 * kTransmittanceMin, "peak alpha ", peak);
  CHECK(o.float_error < 1e-3, "float error ", o.float_error);
}

TEST_CASE(subpixel_and_screen_covering) {
  Scene<double> s = random_scene(6, 6, 33, 17, 3, 2);
  for (int k = 0; k < 3; ++k)
    s.scales[k] = 1e-5, s.scales[3 + k] = 1e-7, s.scales[6 + k] = 1e3, s.scales[9 + k] = 50;
  const Outcome o = run(s, "sub-pixel and screen-covering");
  CHECK(o.render.state.proj.radius[0] > 0, "sub-pixel Gaussian culled");
  CHECK(o.render.state.proj.radius[2] > 0, "screen-covering Gaussian culled");
  CHECK(o.float_error < 1e-3, "float error ", o.float_error);
}

TEST_CASE(ellipse_beside_the_screen) {
  // Thin Gaussians just off each side, long along that side: their bounding circle reaches into
  // the image, their ellipse does not (its tile range was empty, or inverted, and once corrupted
  // the backward's memory). They must be culled.
  Scene<double> s = random_scene(12, 14, 64, 48, 1, -1);
  for (int k = 0; k < 16; ++k) s.cam.viewmat[k] = (k % 5 == 0) ? 1 : 0;
  s.cam.fx = s.cam.fy = 60, s.cam.cx = 32, s.cam.cy = 24;
  const std::int64_t keep = 10;
  const double side[4][2] = {{-30, 24}, {94, 24}, {32, -30}, {32, 78}};  // pixel centres
  for (std::int64_t i = keep; i < s.n; ++i) {
    const double* px = side[i - keep];
    const bool vertical = i - keep < 2;  // long along y beside the left and right edges
    const double z = 2;
    s.means[3 * i] = (px[0] - s.cam.cx) * z / s.cam.fx;
    s.means[3 * i + 1] = (px[1] - s.cam.cy) * z / s.cam.fy;
    s.means[3 * i + 2] = z;
    s.quats[4 * i] = 1, s.quats[4 * i + 1] = s.quats[4 * i + 2] = s.quats[4 * i + 3] = 0;
    s.scales[3 * i] = vertical ? 0.005 : 0.5, s.scales[3 * i + 1] = vertical ? 0.5 : 0.005;
    s.scales[3 * i + 2] = 0.005;
    s.opacities[i] = 0.9;
  }
  check_culled_tail(s, keep, "ellipse beside the screen");
}

TEST_CASE(scattered_around_the_image) {
  // Many Gaussians in and around the view (up to 3 image widths out), anisotropic up to 1e3 in
  // random orientations: the binning invariants above hold for every one of them.
  Scene<double> s = random_scene(13, 3000, 40, 24, 1, -1);
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-1, 1);
  for (std::int64_t i = 0; i < s.n; ++i) {
    for (int k = 0; k < 2; ++k) s.means[3 * i + k] *= 7;
    for (int k = 0; k < 3; ++k) s.scales[3 * i + k] *= std::pow(10.0, 1.5 * u(rng));
  }
  const Outcome o = run(s, "scattered around the image");
  CHECK(o.float_error < 1e-3, "float error ", o.float_error);
}

TEST_CASE(zero_and_nan_quaternions) {
  Scene<double> s = random_scene(7, 12, 33, 17, 3, 0);
  const std::int64_t keep = 10;
  for (int k = 0; k < 4; ++k) s.quats[4 * 10 + k] = 0, s.quats[4 * 11 + k] = k == 2 ? kNaN : 0.5;
  check_culled_tail(s, keep, "zero and NaN quaternions");
}

TEST_CASE(non_finite_parameters) {
  Scene<double> s = random_scene(8, 14, 33, 17, 3, -1);
  const std::int64_t keep = 10;
  s.means[3 * 10 + 1] = kNaN;
  s.scales[3 * 11 + 2] = kInf;
  s.opacities[12] = kNaN;
  s.colors[3 * 13] = -kInf;
  check_culled_tail(s, keep, "non-finite parameters");
}

TEST_CASE(empty_scene) {
  Scene<double> s = random_scene(9, 0, 33, 17, 3, -1);
  const Outcome o = run(s, "empty scene");
  for (std::size_t p = 0; p < o.render.alpha.size(); ++p)
    CHECK(o.render.alpha[p] == 0, "alpha at ", p);
  for (std::size_t k = 0; k < o.render.image.size(); ++k)
    CHECK(o.render.image[k] == s.background[k % 3], "image is not the background at ", k);
}

TEST_CASE(width_or_height_one) {
  const int sizes[][2] = {{1, 1}, {1, 37}, {37, 1}, {17, 16}};
  for (const auto& wh : sizes) {
    Scene<double> s = random_scene(10, 25, wh[0], wh[1], 1, -1);
    char label[64];
    std::snprintf(label, sizeof label, "%dx%d image", wh[0], wh[1]);
    run(s, label);
  }
}

TEST_CASE(clamped_alpha_has_no_opacity_gradient) {
  Scene<double> s = random_scene(11, 1, 13, 9, 1, -1);
  for (int k = 0; k < 3; ++k) s.scales[k] = 1e3;  // G ~ 1 on every pixel
  s.opacities[0] = 1.0;                           // so alpha = min(0.99, G) is clamped everywhere
  const Outcome o = run(s, "clamped alpha");
  // drawn and clamped: a culled Gaussian would pass the zero-gradient checks below vacuously
  CHECK(o.render.state.proj.radius[0] > 0 && o.render.alpha[0] == 0.99, "not drawn clamped");
  CHECK(o.grads.opacities[0] == 0, "opacity gradient ", o.grads.opacities[0]);
  CHECK(o.grads.means[0] == 0 && o.grads.scales[0] == 0, "gradient through a clamped alpha");
}

TEST_CASE(optional_backward_outputs_may_be_null) {
  // grad_background, grad_mean2d and grad_mean2d_abs are optional: left out, the others are the
  // same
  const Scene<double> s = random_scene(18, 20, 33, 17, 3, -1);
  const Render<double> r = render(s);
  const auto gi = random_weights(r.image.size(), 5), ga = random_weights(r.alpha.size(), 6);
  const Grads<double> full = backward(s, r, gi, ga);
  Grads<double> g(s);
  ParamGrads<double> view = g.view();
  rasterize_backward<double>(s.params(), s.cam, s.background.data(), r.state,
                             OutputGrads<double>{gi.data(), ga.data()}, view, nullptr, nullptr,
                             nullptr);
  CHECK(g.means == full.means && g.quats == full.quats && g.scales == full.scales &&
            g.opacities == full.opacities && g.colors == full.colors &&
            std::equal(g.viewmat, g.viewmat + 16, full.viewmat),
        "gradients differ without the optional outputs");
}
