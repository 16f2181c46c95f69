// The compositing's rows (csrc/core/composite.cpp, splat_rows) on thin, turned splats whose boxes
// overlap tiles their ellipses miss: the image and alpha as every pixel composited literally, and
// the rows evaluated, per tile and splat, as documented there: within the splat's box, those whose
// centres lie within a pixel of its ellipse over the tile's columns widened by a pixel; none
// where those columns miss the ellipse.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "harness.hpp"
#include "raster_scene.hpp"

using namespace test;

namespace {

constexpr int kWidth = 61, kHeight = 45, kChannels = 3;  // 4 x 3 tiles, the last ones partial
constexpr std::int64_t kNeedles = 12;  // < 15 a tile: its pixels are never recounted, nor stop
constexpr std::uint32_t kSeeds = 6;

// Image and alpha of `s` in T against the literal compositing of its own projection, in double.
template <typename T>
double literal_error(const Scene<double>& s) {
  const Render<T> r = render(s.cast<T>());
  Projected<double> proj;  // the projection as rendered, in double
  auto to_double = [](const std::vector<T>& v) { return std::vector<double>(v.begin(), v.end()); };
  proj.mean2d = to_double(r.state.proj.mean2d), proj.conic = to_double(r.state.proj.conic);
  proj.opacity = to_double(r.state.proj.opacity), proj.color = to_double(r.state.proj.color);
  const LiteralRender lit =
      render_literally(proj, r.state.bins.order, kWidth, kHeight, kChannels, s.background);
  double err = 0;
  for (std::size_t k = 0; k < lit.image.size(); ++k)
    err = std::max(err, std::abs(lit.image[k] - double(r.image[k])));
  for (std::size_t k = 0; k < lit.alpha.size(); ++k)
    err = std::max(err, std::abs(lit.alpha[k] - double(r.alpha[k])));
  return err;
}

// Boundary points of a splat's ellipse d^T conic d = level, finely sampled (2^18: about 1e-3 px
// apart on a needle 60 px long).
std::vector<double> ellipse_boundary(const Projected<double>& proj, std::int32_t i) {
  const double A = proj.conic[3 * i], B = proj.conic[3 * i + 1], C = proj.conic[3 * i + 2];
  const double det = A * C - B * B, level = support_level(proj.opacity[i]);
  // the covariance [[C, -B], [-B, A]] / det = L L^T, L lower triangular
  const double l11 = std::sqrt(C / det), l21 = -B / det / l11;
  const double l22 = std::sqrt(A / det - l21 * l21);
  const int samples = 1 << 18;
  std::vector<double> xy(2 * samples);  // [samples, 2]
  for (int k = 0; k < samples; ++k) {
    const double phi = 2 * std::acos(-1.0) * k / samples;
    const double u = std::sqrt(level) * std::cos(phi), v = std::sqrt(level) * std::sin(phi);
    xy[2 * k] = proj.mean2d[2 * i] + l11 * u;
    xy[2 * k + 1] = proj.mean2d[2 * i + 1] + l21 * u + l22 * v;
  }
  return xy;
}

// The y range [lo, hi] of the boundary points `xy` whose x lies in [x_lo, x_hi]; false where none
// does.
bool y_range(const std::vector<double>& xy, double x_lo, double x_hi, double& lo, double& hi) {
  lo = 1e300, hi = -1e300;
  for (std::size_t k = 0; k < xy.size(); k += 2)
    if (xy[k] >= x_lo && xy[k] <= x_hi) lo = std::min(lo, xy[k + 1]), hi = std::max(hi, xy[k + 1]);
  return lo <= hi;
}

// Rows of the tile at (x0, y0), w x h, within splat i's box whose centres lie within `pad` of its
// ellipse's boundary points `xy` over the columns [x0 - widen, x0 + w + widen]: 0 where no point
// lies there.
int documented_rows(const Projected<double>& proj, std::int32_t i, const std::vector<double>& xy,
                    int x0, int y0, int w, int h, double widen, double pad) {
  double lo, hi;
  if (!y_range(xy, x0 - widen, x0 + w + widen, lo, hi)) return 0;
  const double my = proj.mean2d[2 * i + 1], ey = proj.extent[2 * i + 1];
  int rows = 0;
  for (int row = std::max(0, int(std::floor(my - ey)) - y0);
       row < std::min(h, int(std::ceil(my + ey)) - y0); ++row) {
    const double centre = y0 + row + 0.5;
    rows += centre >= lo - pad && centre <= hi + pad;
  }
  return rows;
}

// Moves the first `count` needles of `s` along x until the tip of their ellipse (the right one
// for even i, the left one for odd i) lies 0.75 px outside a tile's edge: the columns of the tile
// beyond it, widened by half a pixel, miss the ellipse, which its box (a pixel wider) reaches.
void put_tips_beside_tile_edges(Scene<double>& s, int count) {
  for (int pass = 0; pass < 3; ++pass) {  // the 2D covariance moves a little with the mean
    const Render<double> r = render(s);
    const Projected<double>& proj = r.state.proj;
    for (int i = 0; i < count; ++i) {
      const double A = proj.conic[3 * i], B = proj.conic[3 * i + 1], C = proj.conic[3 * i + 2];
      const double half = std::sqrt(support_level(proj.opacity[i]) * C / (A * C - B * B));
      const double side = i % 2 == 0 ? 1 : -1, tip = proj.mean2d[2 * i] + side * half;
      const double edge = kTileSize * std::clamp(std::round(tip / kTileSize), 1.0,
                                                 std::floor((kWidth - 1.0) / kTileSize));
      s.means[3 * i] += (edge - side * 0.75 - tip) * s.means[3 * i + 2] / s.cam.fx;
    }
  }
}

// Counts of (tile, splat) pairs: the tile's columns, widened by half a pixel, miss the ellipse
// (no rows: the branch q < 0); they meet it but no row of the box lies within a pixel of it; rows
// of the box are left out.
struct Cases {
  int columns_missed = 0, rows_missed = 0, narrowed = 0;
};

// The pairs the forward of `s` in T evaluates against the documented rows, counted with the
// boundary moved by 0.01 px in and out (the sampling's and T's rounding).
template <typename T>
void check_pairs(const Scene<double>& s, std::uint32_t seed, Cases& cases) {
  const Render<T> r = render(s.cast<T>());
  Projected<double> proj;
  auto to_double = [](const std::vector<T>& v) { return std::vector<double>(v.begin(), v.end()); };
  proj.mean2d = to_double(r.state.proj.mean2d), proj.conic = to_double(r.state.proj.conic);
  proj.opacity = to_double(r.state.proj.opacity), proj.extent = to_double(r.state.proj.extent);
  const TileBins& bins = r.state.bins;
  std::vector<std::vector<double>> boundary(s.n);
  for (const std::int32_t i : bins.order) boundary[i] = ellipse_boundary(proj, i);
  constexpr double eps = 0.01;
  std::int64_t fewest = 0, most = 0;
  for (int t = 0; t < bins.tiles_x * bins.tiles_y; ++t) {
    const int x0 = (t % bins.tiles_x) * kTileSize, y0 = (t / bins.tiles_x) * kTileSize;
    const int w = std::min(kTileSize, kWidth - x0), h = std::min(kTileSize, kHeight - y0);
    for (std::int64_t j = bins.offsets[t]; j < bins.offsets[t + 1]; ++j) {
      const std::int32_t i = bins.order[bins.ranks[j]];
      const int inner = documented_rows(proj, i, boundary[i], x0, y0, w, h, 0.5 - eps, 1 - eps);
      const int outer = documented_rows(proj, i, boundary[i], x0, y0, w, h, 0.5 + eps, 1 + eps);
      const int box = documented_rows(proj, i, boundary[i], x0, y0, w, h, 1e300, 1e300);
      fewest += std::int64_t(w) * inner, most += std::int64_t(w) * outer;
      double lo, hi;
      const bool meets = y_range(boundary[i], x0 - 0.5 - eps, x0 + w + 0.5 + eps, lo, hi);
      cases.columns_missed += box > 0 && !meets;
      cases.rows_missed += box > 0 && meets && outer == 0;
      cases.narrowed += outer > 0 && outer < box;
    }
  }
  const std::int64_t pairs = r.state.composite.pairs;
  CHECK(fewest <= pairs && pairs <= most, sizeof(T) == 4 ? "float" : "double", " seed ", seed, ": ",
        pairs, " pairs evaluated, the documented rows hold ", fewest, " to ", most);
}

}  // namespace

TEST_CASE(needles_composite_as_every_pixel_literally) {
  for (std::uint32_t seed = 0; seed < kSeeds; ++seed) {
    const Scene<double> s = smooth_needle_scene(seed + 1, kNeedles, kWidth, kHeight, kChannels);
    const double err_double = literal_error<double>(s), err_float = literal_error<float>(s);
    std::printf("  seed %u: max |op - literal| double %.3g, float %.3g\n", seed, err_double,
                err_float);
    CHECK(err_double < 1e-12, "seed ", seed, ": double, ", err_double);
    CHECK(err_float < 1e-5, "seed ", seed, ": float, ", err_float);
  }
}

TEST_CASE(needles_evaluate_the_documented_rows) {
  Cases cases;
  for (std::uint32_t seed = 0; seed < kSeeds; ++seed) {
    Scene<double> s = needle_scene(seed + 1, kNeedles, kWidth, kHeight, kChannels);
    put_tips_beside_tile_edges(s, 4);
    check_pairs<double>(s, seed, cases);
    check_pairs<float>(s, seed, cases);
  }
  std::printf(
      "  (tile, splat) pairs, float and double: columns miss the ellipse %d, rows miss it %d, "
      "rows left out %d\n",
      cases.columns_missed, cases.rows_missed, cases.narrowed);
  // the cases the test is about occur: 4 needles' tips beside a tile in each scene
  CHECK(cases.columns_missed >= 2 * 4 * int(kSeeds) && cases.rows_missed >= 10 &&
            cases.narrowed >= 10,
        "too few cases");
}
