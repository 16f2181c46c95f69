// Central finite-difference checks, in double, of the rasterizer's gradients: projection alone,
// compositing alone, and end to end, on random small scenes whose sizes are not tile multiples.
#include <algorithm>
#include <cstdio>
#include <functional>
#include <stdexcept>
#include <string>

#include "harness.hpp"
#include "raster_scene.hpp"

using namespace test;

namespace {

constexpr double kStep = 1e-6;

struct Config {
  std::int64_t n;
  int width, height, channels, sh_degree;
};
const Config kConfigs[] = {
    {1, 13, 9, 1, -1},  {7, 13, 9, 3, 0},   {20, 33, 17, 1, 1},
    {50, 33, 17, 3, 2}, {12, 33, 17, 3, 3}, {30, 13, 9, 4, -1},
};

// A 2D filter: plain or antialiased, and the dilation added to each 2D covariance (px^2).
struct Filter {
  bool antialiased;
  double dilation;
  const char* label;
};
// 3DGS's, gsplat's antialiased mode, Mip-Splatting's 2D filter, and the range's ends: a backward
// that took the default dilation for the camera's fails all but the first two
const Filter kFilters[] = {{false, kDilation, ""},
                           {true, kDilation, " antialiased"},
                           {true, 0.1, " antialiased, dilation 0.1"},
                           {false, kMinDilation, " dilation 0.01"},
                           {true, kMaxDilation, " antialiased, dilation 10"}};

// A scene of config `c` away from the alpha and transmittance kinks (`away_from_kinks`), drawn
// with 2D filter `f`.
Scene<double> smooth_scene(const Config& c, std::uint32_t seed, const Filter& f = kFilters[0]) {
  return away_from_kinks(seed, [&](std::uint32_t k) {
    Scene<double> s = random_scene(k, c.n, c.width, c.height, c.channels, c.sh_degree);
    s.cam.antialiased = f.antialiased, s.cam.dilation = f.dilation;
    return s;
  });
}

// A smooth scene of config `c`, its render, and the random weights of a linear loss on its image
// and alpha (of both signs: per-pixel shares cancel as in training).
struct WeightedScene {
  Scene<double> s;
  Render<double> r;
  std::vector<double> w_img, w_alpha;
};
WeightedScene weighted_scene(const Config& c, std::uint32_t scene_seed, std::uint32_t weight_seed,
                             const Filter& f = kFilters[0]) {
  WeightedScene ws{smooth_scene(c, scene_seed, f), {}, {}, {}};
  ws.r = render(ws.s);
  ws.w_img = random_weights(ws.r.image.size(), weight_seed);
  ws.w_alpha = random_weights(ws.r.alpha.size(), weight_seed + 1);
  return ws;
}

// Compares `analytic` with central differences of `loss` in each entry of `values`.
void fd_check(const std::string& what, std::vector<double>& values,
              const std::vector<double>& analytic, const std::function<double()>& loss) {
  double worst = 0;
  for (std::size_t k = 0; k < values.size(); ++k) {
    const double saved = values[k];
    values[k] = saved + kStep;
    const double up = loss();
    values[k] = saved - kStep;
    const double down = loss();
    values[k] = saved;
    const double numeric = (up - down) / (2 * kStep);
    const double err = std::abs(numeric - analytic[k]);
    const double tol = 1e-6 + 1e-5 * std::max(std::abs(numeric), std::abs(analytic[k]));
    worst = std::max(worst, err / tol);
    CHECK(err <= tol, what, "[", k, "]: analytic ", analytic[k], " numeric ", numeric);
  }
  std::printf("  %-22s %4zu entries, worst error/tolerance %.3g\n", what.c_str(), values.size(),
              worst);
}

// fd_check of each Gaussian parameter of `s` and of its view matrix against the gradients `g`.
void fd_check_scene(Scene<double>& s, const Grads<double>& g, const std::function<double()>& loss) {
  fd_check("means", s.means, g.means, loss);
  fd_check("quats", s.quats, g.quats, loss);
  fd_check("scales", s.scales, g.scales, loss);
  fd_check("opacities", s.opacities, g.opacities, loss);
  fd_check("colors", s.colors, g.colors, loss);
  std::vector<double> vm(s.cam.viewmat, s.cam.viewmat + 16);
  auto vm_loss = [&] {
    std::copy(vm.begin(), vm.end(), s.cam.viewmat);
    return loss();
  };
  fd_check("viewmat", vm, std::vector<double>(g.viewmat, g.viewmat + 16), vm_loss);
}

// The compositing's gradients of `r` given those of its image `gi` and alpha `ga`; the
// background's in `dbg` [C].
ProjectedGrads<double> composite_grads(const Scene<double>& s, const Render<double>& r,
                                       const Config& c, const std::vector<double>& gi,
                                       const std::vector<double>& ga, std::vector<double>& dbg) {
  ProjectedGrads<double> dp;
  composite_backward(r.state.proj, r.state.bins, c.width, c.height, c.channels, s.background.data(),
                     r.state.composite, gi.data(), ga.data(), dp, dbg.data());
  return dp;
}

// Central differences of a random linear loss on `s`'s projection (its 2D means, conics, colours,
// opacities and depths) against project_backward's gradients.
void check_projection(Scene<double>& s) {
  Projected<double> proj;
  project_forward(s.params(), s.cam, proj);
  const auto w_m = random_weights(proj.mean2d.size(), 11),
             w_c = random_weights(proj.conic.size(), 12);
  const auto w_col = random_weights(proj.color.size(), 13),
             w_o = random_weights(proj.opacity.size(), 14),
             w_d = random_weights(proj.depth.size(), 15);
  auto loss = [&] {
    Projected<double> p;
    project_forward(s.params(), s.cam, p);
    double l = 0;
    for (std::int64_t i = 0; i < s.n; ++i) {
      if (p.radius[i] == 0) continue;
      for (int k = 0; k < 2; ++k) l += w_m[2 * i + k] * p.mean2d[2 * i + k];
      for (int k = 0; k < 3; ++k) l += w_c[3 * i + k] * p.conic[3 * i + k];
      for (int k = 0; k < s.channels; ++k)
        l += w_col[i * s.channels + k] * p.color[i * s.channels + k];
      l += w_o[i] * p.opacity[i] + w_d[i] * p.depth[i];
    }
    return l;
  };
  ProjectedGrads<double> dp{w_m, w_c, w_o, w_col, w_d};
  for (std::int64_t i = 0; i < s.n; ++i)
    if (proj.radius[i] == 0) std::printf("  (Gaussian %lld culled)\n", (long long)i);
  Grads<double> g(s);
  ParamGrads<double> view = g.view();
  project_backward(s.params(), s.cam, proj, dp, view);
  fd_check_scene(s, g, loss);
}

}  // namespace

TEST_CASE(projection) {
  for (const Filter& f : kFilters)
    for (std::uint32_t seed = 0; seed < std::size(kConfigs); ++seed) {
      const Config& c = kConfigs[seed];
      Scene<double> s = smooth_scene(c, seed + 1, f);
      std::printf(" scene %u%s: N=%lld C=%d sh=%d\n", seed, f.label, (long long)c.n, c.channels,
                  c.sh_degree);
      check_projection(s);
    }
}

// Gaussians whose x/z or y/z lies past the Jacobian's frustum clamp (the image's edge plus
// kClampMargin half-FOVs), on each side and at a corner, wide enough to reach the image: the
// gradient through a clamped coordinate, the derivative of z·bound, against central differences
// (the random scenes lie within the view, where the clamp never acts).
TEST_CASE(projection_past_the_frustum_clamp) {
  Scene<double> s = random_scene(7, 5, 33, 17, 3, 1);
  const Camera<double>& cam = s.cam;
  const double tan_x = 0.5 * cam.width / cam.fx, tan_y = 0.5 * cam.height / cam.fy;
  const double lo_x = -(cam.cx / cam.fx + kClampMargin * tan_x),
               hi_x = (cam.width - cam.cx) / cam.fx + kClampMargin * tan_x;
  const double lo_y = -(cam.cy / cam.fy + kClampMargin * tan_y),
               hi_y = (cam.height - cam.cy) / cam.fy + kClampMargin * tan_y;
  const double mid_x = (lo_x + hi_x) / 2, mid_y = (lo_y + hi_y) / 2, z = 3;
  const double past[5][2] = {{hi_x + 0.5 * tan_x, mid_y},
                             {lo_x - 0.5 * tan_x, mid_y},
                             {mid_x, hi_y + 0.5 * tan_y},
                             {mid_x, lo_y - 0.5 * tan_y},
                             {hi_x + 0.5 * tan_x, lo_y - 0.5 * tan_y}};
  for (int i = 0; i < 5; ++i) {
    const double pc[3] = {past[i][0] * z, past[i][1] * z, z};  // camera space -> world: W^T (p - t)
    for (int k = 0; k < 3; ++k) {
      s.means[3 * i + k] = 0;
      for (int r = 0; r < 3; ++r)
        s.means[3 * i + k] += cam.viewmat[r * 4 + k] * (pc[r] - cam.viewmat[r * 4 + 3]);
    }
    for (int k = 0; k < 3; ++k)  // sigma 7-14 px: they reach 13 px and more into the image
      s.scales[3 * i + k] = (7.0 + 3.5 * k) * z / cam.fx;
  }
  Projected<double> proj;
  project_forward(s.params(), s.cam, proj);
  for (int i = 0; i < 5; ++i) CHECK(proj.radius[i] > 0, "Gaussian ", i, " culled");
  check_projection(s);
}

TEST_CASE(compositing) {
  for (std::uint32_t seed = 0; seed < std::size(kConfigs); ++seed) {
    const Config& c = kConfigs[seed];
    WeightedScene ws = weighted_scene(c, seed + 101, 21);
    Projected<double> proj = ws.r.state.proj;
    auto loss = [&] {
      std::vector<double> image(ws.r.image.size()), alpha(ws.r.alpha.size());
      CompositeState<double> st;
      composite_forward(proj, ws.r.state.bins, c.width, c.height, c.channels,
                        ws.s.background.data(), image.data(), alpha.data(), st);
      return dot(image, ws.w_img) + dot(alpha, ws.w_alpha);
    };
    std::vector<double> dbg(c.channels);
    const ProjectedGrads<double> dp = composite_grads(ws.s, ws.r, c, ws.w_img, ws.w_alpha, dbg);
    std::printf(" scene %u: N=%lld C=%d, %zu visible\n", seed, (long long)c.n, c.channels,
                ws.r.state.bins.order.size());
    fd_check("mean2d", proj.mean2d, dp.mean2d, loss);
    fd_check("conic", proj.conic, dp.conic, loss);
    fd_check("opacity", proj.opacity, dp.opacity, loss);
    fd_check("color", proj.color, dp.color, loss);
    fd_check("background", ws.s.background, dbg, loss);
  }
}

// Thin splats turned at random angles, whose boxes overlap tiles their ellipses miss (the
// compositing leaves out rows there, test_raster_rows.cpp): the compositing's gradients against
// central differences of every pixel composited literally, no row left out.
TEST_CASE(compositing_of_needles_against_the_literal_loop) {
  const Config c{12, 61, 45, 3, -1};
  for (std::uint32_t seed = 0; seed < 2; ++seed) {
    const Scene<double> s = smooth_needle_scene(seed + 401, c.n, c.width, c.height, c.channels);
    const Render<double> r = render(s);
    CHECK(kink_margin(s, r) > 1e-4, "seed ", seed, ": a pixel at a kink");
    const auto w_img = random_weights(r.image.size(), 51),
               w_alpha = random_weights(r.alpha.size(), 52);
    Projected<double> proj = r.state.proj;
    std::vector<double> background = s.background;
    auto loss = [&] {
      const LiteralRender lit =
          render_literally(proj, r.state.bins.order, c.width, c.height, c.channels, background);
      return dot(lit.image, w_img) + dot(lit.alpha, w_alpha);
    };
    std::vector<double> dbg(c.channels);
    const ProjectedGrads<double> dp = composite_grads(s, r, c, w_img, w_alpha, dbg);
    std::printf(" seed %u: %zu visible\n", seed, r.state.bins.order.size());
    fd_check("mean2d", proj.mean2d, dp.mean2d, loss);
    fd_check("conic", proj.conic, dp.conic, loss);
    fd_check("opacity", proj.opacity, dp.opacity, loss);
    fd_check("color", proj.color, dp.color, loss);
    fd_check("background", background, dbg, loss);
  }
}

// The backward reads the splats that its forward gathered: a state that holds none (not a
// forward's of these splats) is refused, not read past its end.
TEST_CASE(backward_refuses_a_state_without_its_forward) {
  const Config& c = kConfigs[0];
  WeightedScene ws = weighted_scene(c, 1, 21);
  CHECK(!ws.r.state.bins.order.empty(), "the scene shows no Gaussian");
  Render<double> stale = ws.r;
  stale.state.composite.splats.clear();
  std::vector<double> dbg(c.channels);
  bool refused = false;
  try {
    composite_grads(ws.s, stale, c, ws.w_img, ws.w_alpha, dbg);
  } catch (const std::invalid_argument&) {
    refused = true;
  }
  CHECK(refused, "a composite state without its forward's splats was accepted");
}

// mean2d_abs (AbsGS's densification signal) is, per Gaussian and axis, the sum over pixels of the
// absolute value of that pixel's share of dL/dmean2d: a loss on one pixel alone has that share.
TEST_CASE(mean2d_abs_sums_per_pixel_shares) {
  for (std::uint32_t seed = 0; seed < std::size(kConfigs); ++seed) {
    const Config& c = kConfigs[seed];
    WeightedScene ws = weighted_scene(c, seed + 301, 41);
    std::vector<double> dbg(c.channels);
    auto backward_with = [&](const std::vector<double>& gi, const std::vector<double>& ga) {
      return composite_grads(ws.s, ws.r, c, gi, ga, dbg);
    };
    const ProjectedGrads<double> full = backward_with(ws.w_img, ws.w_alpha);
    std::vector<double> summed(full.mean2d_abs.size(), 0.0);
    const std::size_t pixels = ws.r.alpha.size();
    for (std::size_t p = 0; p < pixels; ++p) {
      std::vector<double> gi(ws.r.image.size(), 0.0), ga(pixels, 0.0);
      for (int k = 0; k < c.channels; ++k) gi[p * c.channels + k] = ws.w_img[p * c.channels + k];
      ga[p] = ws.w_alpha[p];
      const ProjectedGrads<double> one = backward_with(gi, ga);
      for (std::size_t k = 0; k < summed.size(); ++k) summed[k] += std::abs(one.mean2d[k]);
    }
    double worst = 0, cancelled = 0;  // largest relative error; largest |sum| / sum of |.|
    for (std::size_t k = 0; k < summed.size(); ++k) {
      const double err = std::abs(full.mean2d_abs[k] - summed[k]);
      worst = std::max(worst, err / (1e-12 + summed[k]));
      CHECK(err <= 1e-12 + 1e-9 * summed[k], "mean2d_abs[", k, "] ", full.mean2d_abs[k],
            " per-pixel sum ", summed[k]);
      CHECK(std::abs(full.mean2d[k]) <= full.mean2d_abs[k] * (1 + 1e-12), "|mean2d[", k, "]| ",
            full.mean2d[k], " above mean2d_abs ", full.mean2d_abs[k]);
      if (summed[k] > 0) cancelled = std::max(cancelled, 1 - std::abs(full.mean2d[k]) / summed[k]);
    }
    // random pixel weights make shares of both signs: the test would pass for |mean2d| otherwise
    CHECK(cancelled > 0.1, "no Gaussian's shares cancel (", cancelled, ")");
    std::printf(" scene %u: %zu pixels, worst relative error %.3g, most cancelled %.3g\n", seed,
                pixels, worst, cancelled);
  }
}

TEST_CASE(end_to_end) {
  for (const Filter& f : kFilters)
    for (std::uint32_t seed = 0; seed < std::size(kConfigs); ++seed) {
      const Config& c = kConfigs[seed];
      WeightedScene ws = weighted_scene(c, seed + 201, 31, f);
      auto loss = [&] {
        const Render<double> q = render(ws.s);
        return dot(q.image, ws.w_img) + dot(q.alpha, ws.w_alpha);
      };
      const Grads<double> g = backward(ws.s, ws.r, ws.w_img, ws.w_alpha);
      std::printf(" scene %u%s: N=%lld C=%d sh=%d\n", seed, f.label, (long long)c.n, c.channels,
                  c.sh_degree);
      fd_check_scene(ws.s, g, loss);
      fd_check("background", ws.s.background, g.background, loss);
    }
}
