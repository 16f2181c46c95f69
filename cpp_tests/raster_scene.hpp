// Random Gaussian scenes and a rasterizer runner for the C++ tests.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/finite.hpp"
#include "core/rasterizer.hpp"
#include "harness.hpp"

namespace test {
using namespace spikegs::raster;

template <typename T>
struct Scene {
  std::int64_t n = 0;
  int channels = 3, sh_degree = -1;
  std::vector<T> means, quats, scales, opacities, colors, background;
  Camera<T> cam;
  int coeffs() const { return sh_degree < 0 ? 1 : (sh_degree + 1) * (sh_degree + 1); }
  GaussianParams<T> params() const {
    GaussianParams<T> p{means.data(), quats.data(), scales.data(), opacities.data(), colors.data()};
    p.n = n, p.channels = channels, p.sh_degree = sh_degree, p.sh_coeffs = coeffs();
    return p;
  }
  template <typename U>
  Scene<U> cast() const {
    Scene<U> s;
    s.n = n, s.channels = channels, s.sh_degree = sh_degree;
    auto cv = [](const std::vector<T>& v) { return std::vector<U>(v.begin(), v.end()); };
    s.means = cv(means), s.quats = cv(quats), s.scales = cv(scales), s.opacities = cv(opacities);
    s.colors = cv(colors), s.background = cv(background);
    for (int k = 0; k < 16; ++k) s.cam.viewmat[k] = U(cam.viewmat[k]);
    s.cam.fx = U(cam.fx), s.cam.fy = U(cam.fy), s.cam.cx = U(cam.cx), s.cam.cy = U(cam.cy);
    s.cam.width = cam.width, s.cam.height = cam.height;
    s.cam.near_plane = U(cam.near_plane), s.cam.far_plane = U(cam.far_plane);
    s.cam.antialiased = cam.antialiased, s.cam.dilation = U(cam.dilation);
    return s;
  }
};

// A camera at a small random rotation/translation looking down +z, Gaussians 2-4 units ahead.
inline Scene<double> random_scene(std::uint32_t seed, std::int64_t n, int width, int height,
                                  int channels, int sh_degree) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> g(0, 1);
  Scene<double> s;
  s.n = n, s.channels = channels, s.sh_degree = sh_degree;
  const double f = 1.2 * std::max(width, height);
  s.cam.fx = f * (0.9 + 0.2 * u(rng)), s.cam.fy = f * (0.9 + 0.2 * u(rng));
  s.cam.cx = width * (0.4 + 0.2 * u(rng)), s.cam.cy = height * (0.4 + 0.2 * u(rng));
  s.cam.width = width, s.cam.height = height;
  s.cam.near_plane = 0.01, s.cam.far_plane = 1e10;
  // rotation from a small random axis-angle (Rodrigues), translation small
  double ax = 0.1 * g(rng), ay = 0.1 * g(rng), az = 0.1 * g(rng);
  const double th = std::sqrt(ax * ax + ay * ay + az * az);
  ax /= th, ay /= th, az /= th;
  const double c = std::cos(th), sn = std::sin(th), C1 = 1 - c;
  const double R[3][3] = {{c + ax * ax * C1, ax * ay * C1 - az * sn, ax * az * C1 + ay * sn},
                          {ay * ax * C1 + az * sn, c + ay * ay * C1, ay * az * C1 - ax * sn},
                          {az * ax * C1 - ay * sn, az * ay * C1 + ax * sn, c + az * az * C1}};
  for (int r = 0; r < 4; ++r)
    for (int k = 0; k < 4; ++k)
      s.cam.viewmat[r * 4 + k] = r == 3 ? (k == 3 ? 1.0 : 0.0) : (k == 3 ? 0.1 * g(rng) : R[r][k]);
  for (std::int64_t i = 0; i < n; ++i) {
    // a point 2-4 units ahead in camera space, within the view, mapped back to world space
    const double z = 2 + 2 * u(rng);
    const double pc[3] = {(u(rng) - 0.5) * z * width / f, (u(rng) - 0.5) * z * height / f, z};
    double q[3];
    for (int r = 0; r < 3; ++r) q[r] = pc[r] - s.cam.viewmat[r * 4 + 3];
    for (int k = 0; k < 3; ++k) s.means.push_back(R[0][k] * q[0] + R[1][k] * q[1] + R[2][k] * q[2]);
    for (int k = 0; k < 4; ++k) s.quats.push_back(g(rng));
    const double base = z / f * (1.0 + 3.0 * u(rng));  // a few pixels
    for (int k = 0; k < 3; ++k) s.scales.push_back(base * (0.5 + u(rng)));
    s.opacities.push_back(0.1 + 0.6 * u(rng));
    for (int k = 0; k < s.coeffs() * channels; ++k)
      s.colors.push_back(sh_degree < 0 ? u(rng) : 0.3 * g(rng));
  }
  for (int c = 0; c < channels; ++c) s.background.push_back(u(rng));
  return s;
}

// Every visible Gaussian's tile range is non-empty, on the grid and gathered by its depth rank;
// each tile lists exactly the ranks whose range holds it, ascending (a serial pass rebuilds the
// lists); the rank-major listing (`TileBins::rank_begin`) counts exactly the binned pairs, by
// which the backward's slots index.
template <typename T>
void check_bins(const RasterState<T>& st, const Camera<T>& cam, const char* label) {
  const TileBins& b = st.bins;
  CHECK(b.rank_begin.size() == b.order.size() + 1, label, ": rank_begin size");
  CHECK(b.rect.size() == 4 * b.order.size(), label, ": rect size");
  for (std::size_t rank = 0; rank < b.order.size(); ++rank) {
    const std::int32_t* r = &st.proj.tile_rect[4 * std::size_t(b.order[rank])];
    CHECK(std::equal(r, r + 4, &b.rect[4 * rank]), label, ": rank ", rank,
          "'s gathered tile range differs from its Gaussian's");
    CHECK(0 <= r[0] && r[0] < r[2] && r[2] <= cam.tiles_x() && 0 <= r[1] && r[1] < r[3] &&
              r[3] <= cam.tiles_y(),
          label, ": visible Gaussian ", b.order[rank], " has tile range ", r[0], ",", r[1], " - ",
          r[2], ",", r[3]);
    CHECK(b.rank_begin[rank + 1] - b.rank_begin[rank] == std::int64_t(r[2] - r[0]) * (r[3] - r[1]),
          label, ": rank ", rank, "'s pair count");
  }
  CHECK(b.rank_begin.back() == std::int64_t(b.ranks.size()), label, ": ", b.rank_begin.back(),
        " rank-major pairs against ", b.ranks.size(), " binned");
  std::vector<std::vector<std::int32_t>> lists(std::size_t(cam.tiles_x()) * cam.tiles_y());
  for (std::size_t rank = 0; rank < b.order.size(); ++rank) {
    const std::int32_t* r = &b.rect[4 * rank];
    for (int ty = r[1]; ty < r[3]; ++ty)
      for (int tx = r[0]; tx < r[2]; ++tx)
        lists[std::size_t(ty) * cam.tiles_x() + tx].push_back(std::int32_t(rank));
  }
  CHECK(b.offsets.size() == lists.size() + 1, label, ": offsets size");
  for (std::size_t t = 0; t < lists.size(); ++t)
    CHECK(std::equal(lists[t].begin(), lists[t].end(), b.ranks.begin() + b.offsets[t],
                     b.ranks.begin() + b.offsets[t + 1]),
          label, ": tile ", t, "'s list differs from a serial binning's");
}

template <typename T>
struct Render {
  std::vector<T> image, alpha;
  RasterState<T> state;
};

template <typename T>
Render<T> render(const Scene<T>& s) {
  Render<T> r;
  const std::int64_t pixels = std::int64_t(s.cam.width) * s.cam.height;
  r.image.assign(pixels * s.channels, T(0));
  r.alpha.assign(pixels, T(0));
  rasterize_forward(s.params(), s.cam, s.background.data(), r.image.data(), r.alpha.data(),
                    r.state);
  return r;
}

// Gradients of every input, sized like the inputs.
template <typename T>
struct Grads {
  std::vector<T> means, quats, scales, opacities, colors, background, mean2d, mean2d_abs;
  T viewmat[16] = {};
  explicit Grads(const Scene<T>& s)
      : means(s.means.size()),
        quats(s.quats.size()),
        scales(s.scales.size()),
        opacities(s.opacities.size()),
        colors(s.colors.size()),
        background(s.channels),
        mean2d(2 * s.n),
        mean2d_abs(2 * s.n) {}
  ParamGrads<T> view() {
    return {means.data(), quats.data(), scales.data(), opacities.data(), colors.data(), viewmat};
  }
  bool finite() const {
    using spikegs::all_finite;
    return all_finite(means.data(), long(means.size())) &&
           all_finite(quats.data(), long(quats.size())) &&
           all_finite(scales.data(), long(scales.size())) &&
           all_finite(opacities.data(), long(opacities.size())) &&
           all_finite(colors.data(), long(colors.size())) && all_finite(viewmat, 16) &&
           all_finite(background.data(), long(background.size()));
  }
};

template <typename T>
Grads<T> backward(const Scene<T>& s, const Render<T>& r, const std::vector<T>& gimg,
                  const std::vector<T>& galpha) {
  Grads<T> g(s);
  ParamGrads<T> view = g.view();
  rasterize_backward(s.params(), s.cam, s.background.data(), r.state,
                     OutputGrads<T>{gimg.data(), galpha.data()}, view, g.background.data(),
                     g.mean2d.data(), g.mean2d_abs.data());
  return g;
}

inline std::vector<double> random_weights(std::size_t count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0, 1);
  std::vector<double> w(count);
  for (auto& v : w) v = g(rng);
  return w;
}

inline double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}

// The compositing done literally, in double from the projection `proj` as rendered: every pixel
// over every visible splat in depth order (`order`), no tiles and no rows left out. Calls
// visit(pixel, i, raw, T) for each pair a pixel reaches before it stops (raw = o·G, T its
// transmittance before splat i) and returns each pixel's final transmittance [H * W].
template <typename Visit>
std::vector<double> composite_literally(const Projected<double>& proj,
                                        const std::vector<std::int32_t>& order, int width,
                                        int height, Visit&& visit) {
  std::vector<double> final_T(std::size_t(width) * height, 1.0);
  for (int py = 0; py < height; ++py)
    for (int px = 0; px < width; ++px) {
      const std::int64_t pixel = std::int64_t(py) * width + px;
      double T = 1;
      for (const std::int32_t i : order) {
        const double dx = px + 0.5 - proj.mean2d[2 * i], dy = py + 0.5 - proj.mean2d[2 * i + 1];
        const double power =
            -0.5 * (proj.conic[3 * i] * dx * dx + proj.conic[3 * i + 2] * dy * dy) -
            proj.conic[3 * i + 1] * dx * dy;
        const double raw = proj.opacity[i] * std::exp(power);
        visit(pixel, i, raw, T);
        if (raw < kAlphaMin) continue;
        const double next = T * (1 - std::min(kAlphaMax, raw));
        if (next < kTransmittanceMin) break;
        T = next;
      }
      final_T[pixel] = T;
    }
  return final_T;
}

// Smallest distance, over all (pixel, visible Gaussian) pairs the compositing reaches, of alpha to
// the 1/255 and 0.99 kinks and of the transmittance to the stop threshold (relative): finite
// differences straddling a kink are meaningless, so tests pick scenes away from them.
inline double kink_margin(const Scene<double>& s, const Render<double>& r) {
  double margin = 1e30;
  composite_literally(
      r.state.proj, r.state.bins.order, s.cam.width, s.cam.height,
      [&](std::int64_t, std::int32_t, double raw, double T) {
        margin =
            std::min({margin, std::abs(raw - kAlphaMin) / kAlphaMin, std::abs(raw - kAlphaMax)});
        if (raw < kAlphaMin) return;
        const double next = T * (1 - std::min(kAlphaMax, raw));
        margin = std::min(margin, std::abs(next - kTransmittanceMin) / kTransmittanceMin);
      });
  return margin;
}

// `count` thin Gaussians ("needles"), 3-10 px long (sigma) and 0.05-0.5 px thin, turned at random
// angles in the image plane and opacities 0.2-0.5 (a few overlapping leave every pixel far from
// stopping), seen by an identity camera: their boxes overlap tiles that their ellipses miss.
inline Scene<double> needle_scene(std::uint32_t seed, std::int64_t count, int width, int height,
                                  int channels) {
  Scene<double> s = random_scene(seed, count, width, height, channels, -1);
  for (int k = 0; k < 16; ++k) s.cam.viewmat[k] = (k % 5 == 0) ? 1 : 0;
  const double z = 2, f = 60;
  s.cam.fx = s.cam.fy = f, s.cam.cx = 0.5 * width, s.cam.cy = 0.5 * height;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (std::int64_t i = 0; i < count; ++i) {
    const double px = width * u(rng), py = height * u(rng), angle = std::acos(-1.0) * u(rng);
    s.means[3 * i] = (px - s.cam.cx) * z / f, s.means[3 * i + 1] = (py - s.cam.cy) * z / f;
    s.means[3 * i + 2] = z + 0.01 * i;
    // a turn by `angle` about the view axis (w, x, y, z)
    s.quats[4 * i] = std::cos(angle / 2), s.quats[4 * i + 1] = s.quats[4 * i + 2] = 0;
    s.quats[4 * i + 3] = std::sin(angle / 2);
    s.scales[3 * i] = (3 + 7 * u(rng)) * z / f;
    s.scales[3 * i + 1] = s.scales[3 * i + 2] = (0.05 + 0.45 * u(rng)) * z / f;
    s.opacities[i] = 0.2 + 0.3 * u(rng);
  }
  return s;
}

// The image [H, W, C] and alpha [H, W] of composite_literally, over `background` [C].
struct LiteralRender {
  std::vector<double> image, alpha;
};
inline LiteralRender render_literally(const Projected<double>& proj,
                                      const std::vector<std::int32_t>& order, int width, int height,
                                      int channels, const std::vector<double>& background) {
  LiteralRender out;
  out.image.assign(std::size_t(width) * height * channels, 0.0);
  const std::vector<double> final_T = composite_literally(
      proj, order, width, height, [&](std::int64_t pixel, std::int32_t i, double raw, double T) {
        const double a = std::min(kAlphaMax, raw);
        if (raw < kAlphaMin || T * (1 - a) < kTransmittanceMin) return;
        for (int c = 0; c < channels; ++c)
          out.image[pixel * channels + c] += a * T * proj.color[std::int64_t(i) * channels + c];
      });
  out.alpha.resize(final_T.size());
  for (std::size_t p = 0; p < final_T.size(); ++p) {
    out.alpha[p] = 1 - final_T[p];
    for (int c = 0; c < channels; ++c) out.image[p * channels + c] += final_T[p] * background[c];
  }
  return out;
}

// The first scene `make(seed * 1000 + attempt)` whose compositing stays away from the alpha and
// transmittance kinks; after 50 tries the last, kinks or not: its callers then fail loudly (the
// gradient test checks the margin, the literal comparison in float meets a threshold's flip),
// never pass on a kinked scene.
template <typename Make>
Scene<double> away_from_kinks(std::uint32_t seed, Make make) {
  for (std::uint32_t attempt = 0;; ++attempt) {
    Scene<double> s = make(seed * 1000 + attempt);
    if (kink_margin(s, render(s)) > 1e-4 || attempt == 50) return s;
  }
}

// A needle scene away from the kinks (`away_from_kinks`).
inline Scene<double> smooth_needle_scene(std::uint32_t seed, std::int64_t count, int width,
                                         int height, int channels) {
  return away_from_kinks(
      seed, [&](std::uint32_t k) { return needle_scene(k, count, width, height, channels); });
}

}  // namespace test
