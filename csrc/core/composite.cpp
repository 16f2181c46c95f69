// Tile-parallel compositing. Within a tile, each splat is applied to the rows of its box that its
// ellipse reaches, 16 pixels at a time, so the inner loops (exp included, inlined) vectorise. No
// atomics: the backward writes each (tile, splat) pair's gradient share to a slot of its own and
// sums them in a fixed order. The backward takes those rows as one run of pixels, so that its
// gradient sums are reduced once per (tile, splat) rather than once per row.
#include "core/composite.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/errors.hpp"
#include "core/exp_nonpositive.hpp"
#include "core/scratch.hpp"
#include "core/thread_buffers.hpp"

namespace spikegs::raster {
namespace {

constexpr int kTilePixels = kTileSize * kTileSize;
constexpr int kSplatHeader = 11;  // floats before the colour in a gathered splat
constexpr int kGradHeader = 8;    // floats before the colour in a pair's gradient share
constexpr int kRecount = 16;  // the forward counts a tile's stopped pixels every this many splats

// Splat parameters gathered in depth order: mx, my, the conic's Cholesky factor L (A = l11²,
// B = l11 l21, C = l21² + l22²: `splat_power`), opacity, y half-width; for splat_rows, its
// ellipse's bottom point's dx, -B/C, level/C and det/C²; then colour[C]. The forward gathers them
// and keeps them for the backward (CompositeState::splats), which reads the very values the
// forward composited.
template <typename T>
std::vector<T> gather_splats(const Projected<T>& proj, const TileBins& bins, int channels) {
  const int stride = kSplatHeader + channels;
  const std::int64_t visible = std::int64_t(bins.order.size());
  std::vector<T> out(visible * stride);
#pragma omp parallel for schedule(static) if (visible >= kParallelMinItems)
  for (std::int64_t rank = 0; rank < visible; ++rank) {
    const std::int64_t i = bins.order[rank];
    T* s = out.data() + rank * stride;
    const T A = proj.conic[3 * i], B = proj.conic[3 * i + 1], C = proj.conic[3 * i + 2];
    s[0] = proj.mean2d[2 * i], s[1] = proj.mean2d[2 * i + 1];
    s[5] = proj.opacity[i], s[6] = proj.extent[2 * i + 1];
    // The ellipse alpha >= 1/255 is A dx² + 2B dx dy + C dy² <= level, det = AC - B² of the
    // conic as rounded, taken in double (for float, products exact there: a needle's det loses
    // nothing to cancellation but the last rounding); its bottom point lies at
    // dy = sqrt(level A / det), dx = -B dy / A. A conic that rounding left indefinite gets no
    // chord values: splat_rows keeps its box's rows.
    const double det = double(A) * C - double(B) * B;
    const double level = support_level(double(proj.opacity[i]));
    const bool ellipse = det > 0 && A > 0 && C > 0;
    // L of the conic as rounded, from that det (l22² = det / A); one that rounding left
    // indefinite is taken as the line it nearly is (l22 = 0: the backward's conic gradient stays
    // the form's, a needle whose float32 det is rounding noise, drawn off already)
    const double l11 = A > 0 ? std::sqrt(double(A)) : 0;
    s[2] = T(l11), s[3] = A > 0 ? T(B / l11) : T(0);
    s[4] = A > 0 ? T(std::sqrt(std::max(det, 0.0) / A)) : T(std::sqrt(std::max(double(C), 0.0)));
    const double bottom_dx = ellipse ? -double(B) / A * std::sqrt(level * A / det) : 0;
    const double slope = ellipse ? -double(B) / C : 0, reach = ellipse ? level / C : 0;
    const double narrowing = ellipse ? det / (double(C) * C) : 0;
    // values past T's range (a splat 1e10 px wide) would turn splat_rows's products infinite:
    // such a splat keeps its box's rows
    const double limit = double(std::numeric_limits<T>::max()) * 1e-8;
    const bool fits = std::abs(bottom_dx) < limit && std::abs(slope) < limit && reach < limit &&
                      narrowing < limit;
    s[7] = fits ? T(bottom_dx) : T(0);
    s[8] = fits ? T(slope) : T(0);
    s[9] = fits ? T(reach) : T(0);
    s[10] = fits ? T(narrowing) : T(0);
    for (int c = 0; c < channels; ++c) s[kSplatHeader + c] = proj.color[i * channels + c];
  }
  return out;
}

// power = -(A dx² + C dy²)/2 - B dx dy of a gathered splat `s`, as -(u² + v²)/2 with (u, v) =
// Lᵀ(dx, dy): u = l11 dx + l21 dy, v = l22 dy. Never positive, and without the terms of the
// conic's form, which cancel where a long, thin splat lies far from the pixel along its axis: at
// a dilation of 0.01 a needle centred on a 256² image was 0.037 off in alpha in float32 ~160 px
// away, now 0.002 (the conic's own rounding); 3DGS evaluates the form.
template <typename T>
inline T splat_power(const T* s, T dx, T dy) {
  const T u = s[2] * dx + s[3] * dy, v = s[4] * dy;
  return T(-0.5) * (u * u + v * v);
}

// G = exp(power) for power in [kPowerMin, 0]; exp(kPowerMin) below, where o·exp(-20) < 1e-8 <
// kAlphaMin for any opacity o <= 1 skips the pair. The choice is made on exp's argument, not on
// its result: GCC then keeps the loop branch-free and vectorises it (a select on the result is
// sunk into a branch around the float-to-int conversion, which if-conversion will not take).
constexpr double kPowerMin = -20.0;
template <typename T>
inline T gaussian(T power) {
  return exp_nonpositive(power < T(kPowerMin) ? T(kPowerMin) : power);
}

// Adds one pixel's share of a gathered splat `s`'s geometric gradients: `ga` = G · dL/dalpha is
// dL/d(opacity); through alpha = o·G, G = exp(power), power = -(A dx² + C dy²)/2 - B dx dy, it
// reaches the conic (A, B, C) and the 2D mean (dx = pixel - mean): -d power/d(dx, dy) = (A dx +
// B dy, B dx + C dy) = L (u, v), taken so (`splat_power`: the form's terms cancel); `g_ax`, `g_ay`
// sum the absolute values of the 2D mean's shares (AbsGS: shares of opposite sign do not cancel).
template <typename T>
inline void add_geometry_grad(const T* s, T dx, T dy, T ga, T& g_mx, T& g_my, T& g_A, T& g_B,
                              T& g_C, T& g_o, T& g_ax, T& g_ay) {
  const T dpower = s[5] * ga, u = s[2] * dx + s[3] * dy, v = s[4] * dy;
  const T gx = s[2] * u * dpower, gy = (s[3] * u + s[4] * v) * dpower;
  g_o += ga;
  g_A += T(-0.5) * dx * dx * dpower;
  g_B += -dx * dy * dpower;
  g_C += T(-0.5) * dy * dy * dpower;
  g_mx += gx, g_my += gy;
  g_ax += std::abs(gx), g_ay += std::abs(gy);
}

// Pairs ahead in a tile's list whose splats (and, in the backward, the ranks' tile ranges that
// locate their gradient slots) are prefetched: the splats lie in depth order and a tile reads
// them scattered, a cache miss a pair. On a trained 256² scene (34k Gaussians) fwd+bwd took
// ×0.84-0.92 the time (the less, the busier the machine's memory; 4 to 32 pairs ahead alike),
// ×0.91 on the demo's 128² scene; the images and gradients bitwise the same (BENCHMARKS.md,
// "Rasterizer").
constexpr int kPrefetchAhead = 8;

template <typename T>
inline void prefetch_splat(const T* splats, int stride, std::int32_t rank) {
  const T* s = splats + std::int64_t(rank) * stride;
  __builtin_prefetch(s);
  __builtin_prefetch(s + stride - 1);  // a splat may straddle two cache lines
}

struct Tile {
  int x0, y0, w, h;
  std::int64_t begin, end;  // range in bins.ranks
};

Tile tile_at(const TileBins& bins, std::int64_t t, int width, int height) {
  Tile tile;
  tile.x0 = int(t % bins.tiles_x) * kTileSize;
  tile.y0 = int(t / bins.tiles_x) * kTileSize;
  tile.w = std::min(kTileSize, width - tile.x0);
  tile.h = std::min(kTileSize, height - tile.y0);
  tile.begin = bins.offsets[t];
  tile.end = bins.offsets[t + 1];
  return tile;
}

// Rows of the tile [row0, row1) that a gathered splat `s` can reach: within its box, those whose
// centres lie within a pixel of its ellipse over the tile's columns widened by a pixel (slack
// for rounding). The ellipse's chord at dx spans dy = -(B/C) dx ± sqrt(level/C - (det/C²) dx²);
// its largest dy is at the bottom point (dx = s[7]) or the column nearest it, its smallest at
// the top point (dx = -s[7]) or the column nearest that. A third of the rows in a trained
// scene's splats' boxes lie outside their ellipses there. Never inlined: the forward and the
// backward must agree on every splat's rows, and under -ffast-math two inlined copies may
// round differently.
template <typename T>
[[gnu::noinline]] void splat_rows(const T* s, const Tile& tile, int& row0, int& row1) {
  const T mx = s[0], my = s[1], slope = s[8], reach = s[9], narrowing = s[10];
  // the box's rows, clamped in T before the conversion to int: a splat 2^31 px tall would
  // overflow it
  T top = std::floor(my - s[6]) - T(tile.y0), bottom = std::ceil(my + s[6]) - T(tile.y0);
  if (narrowing > 0) {
    const T left = T(tile.x0) - T(0.5) - mx, right = T(tile.x0 + tile.w) + T(0.5) - mx;
    const T at_bottom = std::clamp(s[7], left, right), at_top = std::clamp(-s[7], left, right);
    const T q_bottom = reach - narrowing * at_bottom * at_bottom;
    const T q_top = reach - narrowing * at_top * at_top;
    if (q_bottom >= 0 && q_top >= 0) {
      const T dy_top = slope * at_top - std::sqrt(q_top);
      const T dy_bottom = slope * at_bottom + std::sqrt(q_bottom);
      top = std::max(top, std::ceil(my + dy_top - T(tile.y0) - T(1.5)));
      bottom = std::min(bottom, std::floor(my + dy_bottom - T(tile.y0) + T(0.5)) + T(1));
    } else {
      bottom = top;  // the tile's columns miss the ellipse
    }
  }
  row0 = int(std::min(std::max(top, T(0)), T(tile.h)));
  row1 = int(std::max(std::min(bottom, T(tile.h)), T(0)));
}

template <typename T, int NC>
void forward_impl(const Projected<T>& proj, const TileBins& bins, int width, int height,
                  int runtime_channels, const T* background, T* image, T* alpha_out,
                  CompositeState<T>& state) {
  const int C = NC > 0 ? NC : runtime_channels;
  const int stride = kSplatHeader + C;
  state.splats = gather_splats(proj, bins, C);
  const std::vector<T>& splats = state.splats;
  const std::int64_t tiles = std::int64_t(bins.tiles_x) * bins.tiles_y;
  state.final_T.assign(std::int64_t(width) * height, T(1));
  state.last.assign(std::int64_t(width) * height, -1);
  std::int64_t pairs = 0;
  ThreadBuffers<T> accumulators(std::size_t(C) * kTilePixels);

#pragma omp parallel reduction(+ : pairs)
  {
    alignas(64) T trans[kTilePixels], active[kTilePixels], weight[kTileSize];
    alignas(64) std::int32_t last[kTilePixels];
    T* const acc = accumulators.local();  // [C, 256]
#pragma omp for schedule(dynamic, 1)
    for (std::int64_t t = 0; t < tiles; ++t) {
      const Tile tile = tile_at(bins, t, width, height);
      std::fill_n(acc, std::size_t(C) * kTilePixels, T(0));
      int row_active[kTileSize];  // pixels of each row still compositing
      for (int p = 0; p < kTilePixels; ++p) {
        const int px = p % kTileSize, py = p / kTileSize;
        trans[p] = 1;
        active[p] = (px < tile.w && py < tile.h) ? T(1) : T(0);
        last[p] = -1;
      }
      for (int row = 0; row < kTileSize; ++row) row_active[row] = row < tile.h ? tile.w : 0;
      int remaining = tile.w * tile.h;
      for (std::int64_t j = tile.begin; j < tile.end && remaining > 0; ++j) {
        // Pixels that stop are counted every kRecount splats, not in each row: a count per row
        // (a horizontal sum) cost a quarter of the loop. Until then a stopped pixel is skipped
        // by its `active` flag, so the result is the same; only fully stopped rows and tiles
        // are found later.
        if ((j - tile.begin) % kRecount == kRecount - 1) {
          remaining = 0;
          for (int row = 0; row < tile.h; ++row) {
            int count = 0;
#pragma omp simd reduction(+ : count)
            for (int x = 0; x < kTileSize; ++x) count += active[row * kTileSize + x] > 0 ? 1 : 0;
            row_active[row] = count;
            remaining += count;
          }
          if (remaining == 0) break;
        }
        if (j + kPrefetchAhead < tile.end)
          prefetch_splat(splats.data(), stride, bins.ranks[j + kPrefetchAhead]);
        const std::int32_t rank = bins.ranks[j];
        const T* s = splats.data() + std::int64_t(rank) * stride;
        const T mx = s[0], my = s[1], o = s[5];
        int row0, row1;
        splat_rows(s, tile, row0, row1);
        const std::int32_t pos = std::int32_t(j - tile.begin);
        for (int row = row0; row < row1; ++row) {
          if (row_active[row] == 0) continue;
          const T dy = T(tile.y0 + row) + T(0.5) - my;
          T* __restrict tr = trans + row * kTileSize;
          T* __restrict act = active + row * kTileSize;
          std::int32_t* __restrict lst = last + row * kTileSize;
          // arithmetic first, in a loop of its own so that exp vectorises
          alignas(64) T alpha[kTileSize];
#pragma omp simd
          for (int x = 0; x < kTileSize; ++x) {
            const T dx = T(tile.x0 + x) + T(0.5) - mx;
            alpha[x] = std::min(alpha_max<T>(), o * gaussian(splat_power(s, dx, dy)));
          }
#pragma omp simd
          for (int x = 0; x < kTileSize; ++x) {
            const T a = alpha[x];
            const bool valid = act[x] > 0 && a >= T(kAlphaMin);
            const T next = tr[x] * (1 - a);
            const bool stop = valid && next < T(kTransmittanceMin);
            const bool take = valid && !stop;
            // each store unconditional, its select on a value (GCC turns `m[x] = c ? v : m[x]`,
            // and `m[x] *= c ? v : 1`, into a masked store behind a branch): T only falls (a >=
            // kAlphaMin), so its update is a minimum with 1 where it stays; pos grows along the
            // tile's list, so the last contributor is a maximum
            weight[x] = take ? a * tr[x] : T(0);
            const T stays = take ? next : T(1);  // T <= 1
            tr[x] = stays < tr[x] ? stays : tr[x];
            const std::int32_t candidate = take ? pos : -1;
            lst[x] = candidate > lst[x] ? candidate : lst[x];
            const T keep = stop ? T(0) : T(1);
            act[x] = keep < act[x] ? keep : act[x];
          }
          pairs += tile.w;
          for (int c = 0; c < C; ++c) {
            const T col = s[kSplatHeader + c];
            T* __restrict ac = acc + std::size_t(c) * kTilePixels + row * kTileSize;
#pragma omp simd
            for (int x = 0; x < kTileSize; ++x) ac[x] += weight[x] * col;
          }
        }
      }
      for (int py = 0; py < tile.h; ++py)
        for (int px = 0; px < tile.w; ++px) {
          const int p = py * kTileSize + px;
          const std::int64_t pix = std::int64_t(tile.y0 + py) * width + tile.x0 + px;
          for (int c = 0; c < C; ++c)
            image[pix * C + c] = acc[std::size_t(c) * kTilePixels + p] +
                                 trans[p] * (background ? background[c] : T(0));
          alpha_out[pix] = 1 - trans[p];
          state.final_T[pix] = trans[p];
          state.last[pix] = last[p];
        }
    }
  }
  state.pairs = pairs;
}

template <typename T, int NC>
void backward_impl(const Projected<T>& proj, const TileBins& bins, int width, int height,
                   int runtime_channels, const T* background, const CompositeState<T>& state,
                   const T* grad_image, const T* grad_alpha, ProjectedGrads<T>& grads,
                   T* grad_background) {
  const int C = NC > 0 ? NC : runtime_channels;
  const int stride = kSplatHeader + C, grad_stride = kGradHeader + C;
  const std::vector<T>& splats = state.splats;
  const std::int64_t tiles = std::int64_t(bins.tiles_x) * bins.tiles_y;
  const std::int64_t visible = std::int64_t(bins.order.size());
  if (std::int64_t(splats.size()) != visible * stride)
    fail("composite_backward: the state is not of a forward of these splats (", splats.size(),
         " gathered values, expected ", visible * stride, ")");
  // Each pair's share of its Gaussian's gradients, in rank-major order: mx, my, A, B, C,
  // opacity, |mx|, |my|, colour[C] ([pairs, 8 + C], left uninitialised: each tile zeroes the
  // slots of its pairs up to its last contributor, and the pairs behind it, which no pixel of
  // the tile reaches, are neither written nor summed); and each tile's share of the
  // background's. Every slot is written by the one thread that owns its tile, and the sums below
  // run in a fixed order, so the gradients are bitwise the same for any thread count.
  const Scratch<T> pair_grads(bins.ranks.size() * grad_stride);
  std::vector<std::int32_t> tile_last(tiles, -1);  // [tiles] rank of the last contributor, -1: none
  std::vector<T> tile_bg(tiles * C, T(0));         // [tiles, C]
  auto slot = [&](std::int32_t rank, std::int64_t t) {  // pair (t, rank)'s gradient share
    return pair_grads.get() + rank_major(bins, rank, t) * grad_stride;
  };
  ThreadBuffers<T> behind_buffers(std::size_t(C) * kTilePixels),
      gimg_buffers(std::size_t(C) * kTilePixels);

#pragma omp parallel
  {
    // Per tile, [256]: pixel centres, T (running back to front), T_final grad_alpha, position of
    // the last contributor.
    alignas(64) T cx[kTilePixels], cy[kTilePixels], trans[kTilePixels], tg[kTilePixels];
    alignas(64) std::int32_t last[kTilePixels];
    alignas(64) T gauss[kTilePixels];  // G of the current splat (the any-C path zeroes it where
                                       // alpha is clamped)
    T* const behind = behind_buffers.local();  // [C, 256]
    T* const gimg = gimg_buffers.local();      // [C, 256]
#pragma omp for schedule(dynamic, 1)
    for (std::int64_t t = 0; t < tiles; ++t) {
      const Tile tile = tile_at(bins, t, width, height);
      std::int32_t max_last = -1, row_last[kTileSize];  // last contributor, per tile and per row
      for (int p = 0; p < kTilePixels; ++p) {
        cx[p] = T(tile.x0 + p % kTileSize) + T(0.5);
        cy[p] = T(tile.y0 + p / kTileSize) + T(0.5);
        trans[p] = T(1), tg[p] = T(0), last[p] = -1;
      }
      for (int c = 0; c < C; ++c) {
        const T bg = background ? background[c] : T(0);
        std::fill_n(behind + std::size_t(c) * kTilePixels, kTilePixels, bg);
        std::fill_n(gimg + std::size_t(c) * kTilePixels, kTilePixels, T(0));
      }
      for (int py = 0; py < kTileSize; ++py) {
        row_last[py] = -1;
        if (py >= tile.h) continue;
        const std::int64_t pix0 = std::int64_t(tile.y0 + py) * width + tile.x0;
        for (int px = 0; px < tile.w; ++px) {
          const int p = py * kTileSize + px;
          const std::int64_t pix = pix0 + px;
          const T tf = state.final_T[pix];
          const std::int32_t lp = state.last[pix];
          trans[p] = tf;
          tg[p] = grad_alpha ? tf * grad_alpha[pix] : T(0);
          last[p] = lp;
          row_last[py] = std::max(row_last[py], lp);
          for (int c = 0; c < C; ++c) {
            const T gi = grad_image[pix * C + c];
            gimg[std::size_t(c) * kTilePixels + p] = gi;
          }
        }
        max_last = std::max(max_last, row_last[py]);
      }
      if (max_last >= 0) tile_last[t] = bins.ranks[tile.begin + max_last];
      for (std::int64_t j = tile.begin; j <= tile.begin + max_last; ++j)  // those left out below
        std::fill_n(slot(bins.ranks[j], t), grad_stride, T(0));           // stay zero
      // the background's share, T_final · dL/dimage, summed in a register and stored once (a
      // sum into tile_bg, pixel by pixel, shared its cache line with the neighbouring tiles',
      // which the other threads were writing); pixels outside the image add 1 · 0
      for (int c = 0; c < C; ++c) {
        const T* gc = gimg + std::size_t(c) * kTilePixels;
        T sum = 0;
        for (int p = 0; p < kTilePixels; ++p) sum += trans[p] * gc[p];
        tile_bg[t * C + c] = sum;
      }
      for (std::int64_t j = tile.begin + max_last; j >= tile.begin; --j) {
        if (j - kPrefetchAhead >= tile.begin) {
          const std::int32_t ahead = bins.ranks[j - kPrefetchAhead];
          prefetch_splat(splats.data(), stride, ahead);
          __builtin_prefetch(&bins.rect[4 * std::int64_t(ahead)]);
          __builtin_prefetch(&bins.rank_begin[ahead]);
        }
        const std::int32_t rank = bins.ranks[j];
        const T* s = splats.data() + std::int64_t(rank) * stride;
        const T mx = s[0], my = s[1], o = s[5];
        const std::int32_t pos = std::int32_t(j - tile.begin);
        int row0, row1;
        splat_rows(s, tile, row0, row1);
        // rows whose pixels all stopped before this splat are left out at both ends; the rest
        // are done as one run of pixels, so that the sums below are reduced once per splat
        while (row0 < row1 && pos > row_last[row0]) ++row0;
        while (row1 > row0 && pos > row_last[row1 - 1]) --row1;
        if (row0 >= row1) continue;
        const int p0 = row0 * kTileSize, p1 = row1 * kTileSize;
        // G = exp(power) in a loop of its own
#pragma omp simd
        for (int p = p0; p < p1; ++p) gauss[p] = gaussian(splat_power(s, cx[p] - mx, cy[p] - my));
        T* out = slot(rank, t);
        T g_mx = 0, g_my = 0, g_A = 0, g_B = 0, g_C = 0, g_o = 0, g_ax = 0, g_ay = 0;
        if constexpr (NC > 0) {
          // alpha, T, the colour and the geometric gradients in one pass: every load is
          // unconditional and every conditional a select, so that the loop vectorises
          T col[NC], gc[NC] = {};
          for (int c = 0; c < NC; ++c) col[c] = s[kSplatHeader + c];
#pragma omp simd reduction(+ : g_mx, g_my, g_A, g_B, g_C, g_o, g_ax, g_ay, gc[ : NC])
          for (int p = p0; p < p1; ++p) {
            const T G = gauss[p], raw = o * G, tr = trans[p], tgp = tg[p];
            const std::int32_t lp = last[p];
            const T dx = cx[p] - mx, dy = cy[p] - my;
            const T a = std::min(alpha_max<T>(), raw);
            const bool valid = pos <= lp && a >= T(kAlphaMin);
            const T inv = T(1) / (1 - a);  // 1 - a >= 1 - kAlphaMax
            const T before = tr * (valid ? inv : T(1));
            trans[p] = before;
            const T al = valid ? a : T(0), t = valid ? before : T(0);
            T da = valid ? tgp * inv : T(0);
#pragma GCC unroll 4
            for (int c = 0; c < NC; ++c) {
              T* __restrict bh = behind + std::size_t(c) * kTilePixels;
              const T w = t * gimg[std::size_t(c) * kTilePixels + p];
              const T diff = col[c] - bh[p];
              da += diff * w;
              gc[c] += al * w;
              bh[p] += al * diff;
            }
            const T ga = valid && raw < alpha_max<T>() ? G * da : T(0);  // 0 where alpha is clamped
            add_geometry_grad(s, dx, dy, ga, g_mx, g_my, g_A, g_B, g_C, g_o, g_ax, g_ay);
          }
          for (int c = 0; c < NC; ++c) out[kGradHeader + c] += gc[c];
        } else {
          // any channel count: the same in three passes, the channels one at a time
          alignas(64) T alph[kTilePixels], tj[kTilePixels], dalpha[kTilePixels];
#pragma omp simd
          for (int p = p0; p < p1; ++p) {
            const T G = gauss[p], raw = o * G, tr = trans[p], tgp = tg[p];
            const std::int32_t lp = last[p];
            const T a = std::min(alpha_max<T>(), raw);
            const bool valid = pos <= lp && a >= T(kAlphaMin);
            const T inv = T(1) / (1 - a);
            const T before = tr * (valid ? inv : T(1));
            trans[p] = before;
            alph[p] = valid ? a : T(0);
            tj[p] = valid ? before : T(0);
            dalpha[p] = valid ? tgp * inv : T(0);
            gauss[p] = valid && raw < alpha_max<T>() ? G : T(0);
          }
          for (int c = 0; c < C; ++c) {
            const T col = s[kSplatHeader + c];
            T* __restrict bh = behind + std::size_t(c) * kTilePixels;
            const T* __restrict gi = gimg + std::size_t(c) * kTilePixels;
            T sum = 0;
#pragma omp simd reduction(+ : sum)
            for (int p = p0; p < p1; ++p) {
              const T w = tj[p] * gi[p];
              const T diff = col - bh[p];
              dalpha[p] += diff * w;
              sum += alph[p] * w;
              bh[p] += alph[p] * diff;
            }
            out[kGradHeader + c] += sum;
          }
#pragma omp simd reduction(+ : g_mx, g_my, g_A, g_B, g_C, g_o, g_ax, g_ay)
          for (int p = p0; p < p1; ++p) {
            const T dx = cx[p] - mx, dy = cy[p] - my;
            add_geometry_grad(s, dx, dy, gauss[p] * dalpha[p], g_mx, g_my, g_A, g_B, g_C, g_o, g_ax,
                              g_ay);
          }
        }
        out[0] += g_mx, out[1] += g_my, out[2] += g_A, out[3] += g_B, out[4] += g_C, out[5] += g_o;
        out[6] += g_ax, out[7] += g_ay;
      }
    }
  }

  const std::int64_t n = std::int64_t(proj.radius.size());
  grads.mean2d.assign(2 * n, T(0));
  grads.mean2d_abs.assign(2 * n, T(0));
  grads.conic.assign(3 * n, T(0));
  grads.opacity.assign(n, T(0));
  grads.color.assign(n * C, T(0));
#pragma omp parallel for schedule(static)
  for (std::int64_t rank = 0; rank < visible; ++rank) {
    const std::int64_t i = bins.order[rank];
    const std::int32_t* rect = &bins.rect[4 * rank];  // the rank's tiles in rank-major order
    std::int64_t k = bins.rank_begin[rank];
    for (std::int64_t ty = rect[1]; ty < rect[3]; ++ty)
      for (std::int64_t tx = rect[0]; tx < rect[2]; ++tx, ++k) {
        if (rank > tile_last[ty * bins.tiles_x + tx]) continue;  // behind: its slot unwritten
        const T* s = pair_grads.get() + k * grad_stride;
        grads.mean2d[2 * i] += s[0], grads.mean2d[2 * i + 1] += s[1];
        grads.conic[3 * i] += s[2], grads.conic[3 * i + 1] += s[3], grads.conic[3 * i + 2] += s[4];
        grads.opacity[i] += s[5];
        grads.mean2d_abs[2 * i] += s[6], grads.mean2d_abs[2 * i + 1] += s[7];
        for (int c = 0; c < C; ++c) grads.color[i * C + c] += s[kGradHeader + c];
      }
  }
  if (grad_background)
    for (int c = 0; c < C; ++c) {
      grad_background[c] = 0;
      for (std::int64_t t = 0; t < tiles; ++t) grad_background[c] += tile_bg[t * C + c];
    }
}

}  // namespace

template <typename T>
void composite_forward(const Projected<T>& proj, const TileBins& bins, int width, int height,
                       int channels, const T* background, T* image, T* alpha,
                       CompositeState<T>& state) {
  if (channels == 1)
    return forward_impl<T, 1>(proj, bins, width, height, 1, background, image, alpha, state);
  if (channels == 3)
    return forward_impl<T, 3>(proj, bins, width, height, 3, background, image, alpha, state);
  forward_impl<T, 0>(proj, bins, width, height, channels, background, image, alpha, state);
}

template <typename T>
void composite_backward(const Projected<T>& proj, const TileBins& bins, int width, int height,
                        int channels, const T* background, const CompositeState<T>& state,
                        const T* grad_image, const T* grad_alpha, ProjectedGrads<T>& grads,
                        T* grad_background) {
  if (channels == 1)
    return backward_impl<T, 1>(proj, bins, width, height, 1, background, state, grad_image,
                               grad_alpha, grads, grad_background);
  if (channels == 3)
    return backward_impl<T, 3>(proj, bins, width, height, 3, background, state, grad_image,
                               grad_alpha, grads, grad_background);
  backward_impl<T, 0>(proj, bins, width, height, channels, background, state, grad_image,
                      grad_alpha, grads, grad_background);
}

template void composite_forward<float>(const Projected<float>&, const TileBins&, int, int, int,
                                       const float*, float*, float*, CompositeState<float>&);
template void composite_forward<double>(const Projected<double>&, const TileBins&, int, int, int,
                                        const double*, double*, double*, CompositeState<double>&);
template void composite_backward<float>(const Projected<float>&, const TileBins&, int, int, int,
                                        const float*, const CompositeState<float>&, const float*,
                                        const float*, ProjectedGrads<float>&, float*);
template void composite_backward<double>(const Projected<double>&, const TileBins&, int, int, int,
                                         const double*, const CompositeState<double>&,
                                         const double*, const double*, ProjectedGrads<double>&,
                                         double*);

}  // namespace spikegs::raster
