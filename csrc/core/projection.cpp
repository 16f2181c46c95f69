// EWA projection, forward and backward; see docs/rasterizer.md for the maths step by step.
#include "core/projection.hpp"

#include <algorithm>
#include <cmath>
#include <glm/glm.hpp>
#include <limits>

#include "core/finite.hpp"
#include "core/sh.hpp"

namespace spikegs::raster {
namespace {

template <typename T>
using Vec3 = glm::vec<3, T, glm::defaultp>;
template <typename T>
using Mat3 = glm::mat<3, 3, T, glm::defaultp>;

// glm is column-major: m[column][row].
template <typename T>
Mat3<T> rotation_of(const T* viewmat) {
  Mat3<T> w;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) w[c][r] = viewmat[r * 4 + c];
  return w;
}

template <typename T>
Mat3<T> quat_to_rotation(T w, T x, T y, T z) {
  Mat3<T> r;
  r[0][0] = 1 - 2 * (y * y + z * z), r[1][0] = 2 * (x * y - w * z), r[2][0] = 2 * (x * z + w * y);
  r[0][1] = 2 * (x * y + w * z), r[1][1] = 1 - 2 * (x * x + z * z), r[2][1] = 2 * (y * z - w * x);
  r[0][2] = 2 * (x * z - w * y), r[1][2] = 2 * (y * z + w * x), r[2][2] = 1 - 2 * (x * x + y * y);
  return r;
}

// d(loss)/d(w, x, y, z) for R = quat_to_rotation(w, x, y, z), given g = d(loss)/dR.
template <typename T>
void quat_to_rotation_vjp(T w, T x, T y, T z, const Mat3<T>& g, T out[4]) {
  auto G = [&](int r, int c) { return g[c][r]; };
  out[0] = 2 * (-z * G(0, 1) + y * G(0, 2) + z * G(1, 0) - x * G(1, 2) - y * G(2, 0) + x * G(2, 1));
  out[1] = 2 * (y * G(0, 1) + z * G(0, 2) + y * G(1, 0) - 2 * x * G(1, 1) - w * G(1, 2) +
                z * G(2, 0) + w * G(2, 1) - 2 * x * G(2, 2));
  out[2] = 2 * (-2 * y * G(0, 0) + x * G(0, 1) + w * G(0, 2) + x * G(1, 0) + z * G(1, 2) -
                w * G(2, 0) + z * G(2, 1) - 2 * y * G(2, 2));
  out[3] = 2 * (-2 * z * G(0, 0) - w * G(0, 1) + x * G(0, 2) + w * G(1, 0) - 2 * z * G(1, 1) +
                y * G(1, 2) + x * G(2, 0) + y * G(2, 1));
}

// Everything the forward computes for one Gaussian that the backward needs again.
template <typename T>
struct Splat {
  bool visible = false;
  T qinv;            // 1 / |q|
  T qn[4];           // normalised quaternion
  Mat3<T> R, M, WM;  // rotation, R diag(s), W M
  Vec3<T> p;         // camera-space mean
  T u_x, u_y;        // clamped x/z and y/z
  bool clamped_x, clamped_y;
  Vec3<T> J0, J1;  // rows of the projection Jacobian
  Vec3<T> V0, V1;  // rows of V = J W M
  T a, b, c, det;  // 2D covariance (+ dilation) and its determinant
  T area;          // antialiased: |V0 x V1| = sqrt(det(V V^T)), the undilated covariance's
  T compensation;  // the opacity's factor: area / sqrt(det) where antialiased, else 1
};

template <typename T>
Splat<T> build_splat(const GaussianParams<T>& prm, const Camera<T>& cam, std::int64_t i) {
  Splat<T> s;
  const T* mean = prm.means + 3 * i;
  const T* quat = prm.quats + 4 * i;
  const T* scale = prm.scales + 3 * i;
  if (!all_finite(mean, 3) || !all_finite(quat, 4) || !all_finite(scale, 3) ||
      !is_finite(prm.opacities[i]) ||
      !all_finite(prm.colors + i * prm.color_stride(), prm.color_stride()))
    return s;
  const T qq = quat[0] * quat[0] + quat[1] * quat[1] + quat[2] * quat[2] + quat[3] * quat[3];
  // culled below the smallest normal: -ffast-math's reciprocal square root made -inf of a
  // subnormal |q|^2 (|q| < 1.1e-19 in float32), and 1/|q| there would reach the gradient
  if (!(qq >= std::numeric_limits<T>::min()) || !is_finite(qq)) return s;
  s.qinv = T(1) / std::sqrt(qq);
  for (int k = 0; k < 4; ++k) s.qn[k] = quat[k] * s.qinv;

  const Mat3<T> W = rotation_of(cam.viewmat);
  const Vec3<T> t(cam.viewmat[3], cam.viewmat[7], cam.viewmat[11]);
  s.p = W * Vec3<T>(mean[0], mean[1], mean[2]) + t;
  const T z = s.p.z;
  if (!(z > cam.near_plane && z < cam.far_plane)) return s;
  // the Jacobian's depth terms take z^2: where it leaves the normal range, or fx / z^2 the
  // finite one, the gradients of the mean and the view matrix were NaN or inf while the forward
  // drew the splat (float32: a Gaussian 1e20 away, or 1e-19 near with fx 30); float32 draws z
  // up to 1.8e19, down to max(1.1e-19, 5.4e-20 sqrt(fx)), float64 up to 1.3e154.
  // Bounds on z itself: a z^2 here changed the Jacobian's rounding under -ffast-math.
  const T root_max = std::sqrt(std::numeric_limits<T>::max());
  const T z_min = std::max(std::sqrt(std::numeric_limits<T>::min()),
                           std::sqrt(std::max(cam.fx, cam.fy)) / root_max);
  if (!(z >= z_min && z <= root_max)) return s;

  s.R = quat_to_rotation(s.qn[0], s.qn[1], s.qn[2], s.qn[3]);
  s.M = s.R;
  for (int c = 0; c < 3; ++c) s.M[c] *= scale[c];
  s.WM = W * s.M;

  const T tan_x = T(0.5) * cam.width / cam.fx, tan_y = T(0.5) * cam.height / cam.fy;
  const T margin = T(kClampMargin);
  const T lo_x = -(cam.cx / cam.fx + margin * tan_x),
          hi_x = (cam.width - cam.cx) / cam.fx + margin * tan_x;
  const T lo_y = -(cam.cy / cam.fy + margin * tan_y),
          hi_y = (cam.height - cam.cy) / cam.fy + margin * tan_y;
  const T ux = s.p.x / z, uy = s.p.y / z;
  s.u_x = std::min(std::max(ux, lo_x), hi_x);
  s.u_y = std::min(std::max(uy, lo_y), hi_y);
  s.clamped_x = !(ux >= lo_x && ux <= hi_x);
  s.clamped_y = !(uy >= lo_y && uy <= hi_y);
  const T tx = z * s.u_x, ty = z * s.u_y;
  s.J0 = Vec3<T>(cam.fx / z, 0, -cam.fx * tx / (z * z));
  s.J1 = Vec3<T>(0, cam.fy / z, -cam.fy * ty / (z * z));
  s.V0 = glm::transpose(s.WM) * s.J0;
  s.V1 = glm::transpose(s.WM) * s.J1;
  const T eps = cam.dilation;
  const T n0 = glm::dot(s.V0, s.V0), n1 = glm::dot(s.V1, s.V1);
  const Vec3<T> cr = glm::cross(s.V0, s.V1);
  s.a = n0 + eps;
  s.b = glm::dot(s.V0, s.V1);
  s.c = n1 + eps;
  s.det = glm::dot(cr, cr) + eps * (n0 + n1) + eps * eps;
  if (!(s.det > 0) || !is_finite(s.det) || !is_finite(s.a) || !is_finite(s.b) || !is_finite(s.c))
    return s;
  // the backward's largest terms (V1 x (V0 x V1)) reach 2 |V|^3: where that overflows while the
  // projection stays finite (a float32 needle ~1e18 long) its gradients were 0 * inf, NaN, and
  // the view matrix's too through their sum
  const T n_max = std::max(n0, n1);
  if (!is_finite(T(2) * n_max * std::sqrt(n_max))) return s;
  s.area = cam.antialiased ? std::sqrt(glm::dot(cr, cr)) : T(0);
  if (cam.antialiased && !(s.area > 0)) return s;  // flat: the compensation, opacity 0
  s.compensation = cam.antialiased ? s.area / std::sqrt(s.det) : T(1);
  s.visible = true;
  return s;
}

// Viewing direction for SH: unit vector from the camera centre to the mean, and that distance;
// zero at the centre (a mean there is culled unless the viewmat is not rigid: -W^T t is then not
// the camera's centre), where every SH band above 0 is zero, and where the offset itself is not
// finite (a non-rigid viewmat's). Where |d|^2 leaves the normal range, d is normalised by its
// largest component first: |d|^2 overflowed past 1.8e19 in float32 (a black splat, NaN
// gradients) and 1.3e154 in double (band 0 alone), and underflowed to a zero direction.
template <typename T>
Vec3<T> view_direction(const T* mean, const Camera<T>& cam, T& length) {
  const Mat3<T> W = rotation_of(cam.viewmat);
  const Vec3<T> t(cam.viewmat[3], cam.viewmat[7], cam.viewmat[11]);
  const Vec3<T> d = Vec3<T>(mean[0], mean[1], mean[2]) + glm::transpose(W) * t;  // mean - campos
  const T squared = glm::dot(d, d);
  if (is_finite(squared) && squared >= std::numeric_limits<T>::min()) {
    length = std::sqrt(squared);
    return d / length;
  }
  const T largest = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
  if (!(largest > T(0)) || !is_finite(largest)) {
    length = T(0);
    return Vec3<T>(T(0));
  }
  const Vec3<T> scaled = d / largest;  // its largest component +-1: |scaled| in [1, sqrt 3]
  const T scaled_length = glm::length(scaled);
  length = largest * scaled_length;
  return scaled / scaled_length;
}

}  // namespace

template <typename T>
void project_forward(const GaussianParams<T>& prm, const Camera<T>& cam, Projected<T>& out) {
  const std::int64_t n = prm.n;
  const int C = prm.channels;
  out.mean2d.assign(2 * n, T(0));
  out.conic.assign(3 * n, T(0));
  out.depth.assign(n, T(0));
  out.opacity.assign(n, T(0));
  out.color.assign(n * C, T(0));
  out.radius.assign(n, 0);
  out.extent.assign(2 * n, T(0));
  out.tile_rect.assign(4 * n, 0);
  const int tiles_x = cam.tiles_x(), tiles_y = cam.tiles_y();

#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i) {
    const Splat<T> s = build_splat(prm, cam, i);
    if (!s.visible) continue;
    const T o = prm.opacities[i] * s.compensation;
    if (!(o >= T(kAlphaMin))) continue;
    const T mx = cam.fx * s.p.x / s.p.z + cam.cx, my = cam.fy * s.p.y / s.p.z + cam.cy;
    if (!(std::abs(mx) < T(kMaxMean2d) && std::abs(my) < T(kMaxMean2d))) continue;
    const T mid = T(0.5) * (s.a + s.c);
    const T lambda = mid + std::sqrt(std::max(T(0.1), mid * mid - s.det));
    // alpha >= 1/255 inside the ellipse d^T conic d <= 2 ln(255 o), whose bounding circle is r
    const T level = support_level(o);
    const T r = std::ceil(std::sqrt(level * lambda));
    if (!(r >= T(1))) continue;  // o <= 1/255 (level <= 0): no pixel but its centre reaches 1/255
    auto reaches_image = [&](T half_x, T half_y) {  // the box mean ± half-widths overlaps it
      return mx + half_x > 0 && mx - half_x < cam.width && my + half_y > 0 &&
             my - half_y < cam.height;
    };
    if (!reaches_image(r, r)) continue;
    // binning uses the ellipse's own x and y half-widths (tighter), plus a pixel of slack; that
    // box can miss the image where the bounding circle does not, and then the Gaussian is culled
    // (its tile range would be empty or inverted)
    const T ex = std::sqrt(level * s.a) + 1, ey = std::sqrt(level * s.c) + 1;
    if (!reaches_image(ex, ey)) continue;
    const T ts = T(kTileSize);
    auto tile = [](T v, int tiles) { return std::int32_t(std::clamp(v, T(0), T(tiles))); };
    const std::int32_t x0 = tile(std::floor((mx - ex) / ts), tiles_x);
    const std::int32_t y0 = tile(std::floor((my - ey) / ts), tiles_y);
    const std::int32_t x1 = tile(std::floor((mx + ex) / ts) + 1, tiles_x);
    const std::int32_t y1 = tile(std::floor((my + ey) / ts) + 1, tiles_y);
    out.radius[i] = std::int32_t(std::min(r, T(1 << 30)));
    out.extent[2 * i] = ex;
    out.extent[2 * i + 1] = ey;
    out.tile_rect[4 * i + 0] = x0;
    out.tile_rect[4 * i + 1] = y0;
    out.tile_rect[4 * i + 2] = x1;
    out.tile_rect[4 * i + 3] = y1;
    out.mean2d[2 * i] = mx;
    out.mean2d[2 * i + 1] = my;
    out.conic[3 * i] = s.c / s.det;
    out.conic[3 * i + 1] = -s.b / s.det;
    out.conic[3 * i + 2] = s.a / s.det;
    out.depth[i] = s.p.z;
    out.opacity[i] = o;
    const T* col = prm.colors + i * prm.color_stride();
    T* dst = out.color.data() + i * C;
    if (prm.sh_degree < 0) {
      for (int c = 0; c < C; ++c) dst[c] = col[c];
    } else {
      T length = 0;  // degree 0's one band does not depend on the direction
      const Vec3<T> dir =
          prm.sh_degree > 0 ? view_direction(prm.means + 3 * i, cam, length) : Vec3<T>(T(0));
      T basis[16];
      sh_basis(prm.sh_degree, dir.x, dir.y, dir.z, basis);
      const int K = (prm.sh_degree + 1) * (prm.sh_degree + 1);
      for (int c = 0; c < C; ++c) {
        T v = T(0.5);
        for (int k = 0; k < K; ++k) v += basis[k] * col[k * C + c];
        dst[c] = std::max(v, T(0));
      }
    }
  }
}

template <typename T>
void project_backward(const GaussianParams<T>& prm, const Camera<T>& cam, const Projected<T>& proj,
                      const ProjectedGrads<T>& dp, ParamGrads<T>& g) {
  const std::int64_t n = prm.n;
  const int C = prm.channels;
  // The view matrix's gradient is summed per block of Gaussians, then over blocks in order: the
  // same sums for any thread count.
  constexpr std::int64_t kBlock = 256;
  const std::int64_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<Mat3<T>> dW_block(blocks, Mat3<T>(T(0)));
  std::vector<Vec3<T>> dt_block(blocks, Vec3<T>(T(0)));
  const Mat3<T> W = rotation_of(cam.viewmat);
  const Vec3<T> t(cam.viewmat[3], cam.viewmat[7], cam.viewmat[11]);

#pragma omp parallel for schedule(dynamic, 4)
  for (std::int64_t b = 0; b < blocks; ++b) {
    Mat3<T> dW(T(0));
    Vec3<T> dt(T(0));
    for (std::int64_t i = b * kBlock; i < std::min(n, (b + 1) * kBlock); ++i) {
      if (proj.radius[i] == 0) continue;
      const Splat<T> s = build_splat(prm, cam, i);
      if (!s.visible) continue;  // inputs not the forward's (a direct caller): s is unset
      const T* mean = prm.means + 3 * i;
      const T* scale = prm.scales + 3 * i;
      const Vec3<T> mu(mean[0], mean[1], mean[2]);
      Vec3<T> dmu(T(0)), dpc(T(0));  // gradients of the world mean and the camera-space mean

      g.opacities[i] += dp.opacity[i] * s.compensation;

      // colour
      const T* col = prm.colors + i * prm.color_stride();
      T* dcol = g.colors + i * prm.color_stride();
      const T* dcolor = dp.color.data() + i * C;
      if (prm.sh_degree < 0) {
        for (int c = 0; c < C; ++c) dcol[c] += dcolor[c];
      } else {
        T length = 0;  // degree 0: no direction, and no gradient through it
        const Vec3<T> dir = prm.sh_degree > 0 ? view_direction(mean, cam, length) : Vec3<T>(T(0));
        T basis[16], weight[16];
        sh_basis(prm.sh_degree, dir.x, dir.y, dir.z, basis);
        const int K = (prm.sh_degree + 1) * (prm.sh_degree + 1);
        for (int k = 0; k < K; ++k) weight[k] = 0;
        for (int c = 0; c < C; ++c) {
          if (proj.color[i * C + c] <= 0) {  // clamped at 0: recompute to see if it was active
            T v = T(0.5);
            for (int k = 0; k < K; ++k) v += basis[k] * col[k * C + c];
            if (v < 0) continue;
          }
          for (int k = 0; k < K; ++k) {
            dcol[k * C + c] += basis[k] * dcolor[c];
            weight[k] += col[k * C + c] * dcolor[c];
          }
        }
        if (prm.sh_degree > 0) {
          T ddir[3] = {0, 0, 0};
          sh_basis_vjp(prm.sh_degree, dir.x, dir.y, dir.z, weight, ddir);
          const Vec3<T> gd(ddir[0], ddir[1], ddir[2]);
          const Vec3<T> dd =  // through normalisation; none at the centre, where it has no slope
              length > T(0) ? (gd - dir * glm::dot(dir, gd)) / length : Vec3<T>(T(0));
          dmu += dd;
          // d = mean + W^T t: d/dW = t dd^T, d/dt = W dd
          dW += glm::outerProduct(t, dd);
          dt += W * dd;
        }
      }

      // conic = (c, -b, a) / det, det = |V0 x V1|^2 + eps (n0 + n1) + eps^2, differentiated as
      // the forward computes it. The chain through the inverse (dcov = -Q G Q, then
      // dV0 = 2 da V0 + db V1) cancels large terms for a needle, whose V0 and V1 are nearly
      // parallel: float32 gradients of a 1000 x 0.2 px splat were 5 % off.
      const T g0 = dp.conic[3 * i], g1 = dp.conic[3 * i + 1], g2 = dp.conic[3 * i + 2];
      const T idet = T(1) / s.det, eps = cam.dilation;
      // each term scaled by 1/det before the sum: for a float32 needle of ~1e18 the terms
      // overflow, or idet^2 underflows to 0 (inf * 0: NaN), while ddet itself is small
      T ddet = -(g0 * (s.c * idet) - g1 * (s.b * idet) + g2 * (s.a * idet)) * idet;
      const Vec3<T> cr = glm::cross(s.V0, s.V1);
      Vec3<T> dV0 = T(2) * g2 * idet * s.V0 - g1 * idet * s.V1;
      Vec3<T> dV1 = T(2) * g0 * idet * s.V1 - g1 * idet * s.V0;
      if (cam.antialiased) {
        // compensation = |cr| / sqrt(det): d|cr| = u . d(cr), u = cr / |cr| (|cr| > 0: visible),
        // bounded as a splat flattens, where gsplat's d sqrt(det_o) / d det_o is not
        const T dcomp = dp.opacity[i] * prm.opacities[i], isqrt = T(1) / std::sqrt(s.det);
        const Vec3<T> u = cr / s.area;
        ddet -= T(0.5) * dcomp * s.compensation * idet;
        dV0 += dcomp * isqrt * glm::cross(s.V1, u);
        dV1 += dcomp * isqrt * glm::cross(u, s.V0);
      }
      dV0 += ddet * (T(2) * glm::cross(s.V1, cr) + T(2) * eps * s.V0);
      dV1 += ddet * (T(2) * glm::cross(cr, s.V0) + T(2) * eps * s.V1);
      // V_r = (W M)^T J_r
      Vec3<T> dJ0 = s.WM * dV0, dJ1 = s.WM * dV1;
      const Mat3<T> dWM = glm::outerProduct(s.J0, dV0) + glm::outerProduct(s.J1, dV1);
      dW += dWM * glm::transpose(s.M);
      const Mat3<T> dM = glm::transpose(W) * dWM;
      Mat3<T> dR;
      for (int c = 0; c < 3; ++c) {
        g.scales[3 * i + c] += glm::dot(dM[c], s.R[c]);
        dR[c] = dM[c] * scale[c];
      }
      T dqn[4];
      quat_to_rotation_vjp(s.qn[0], s.qn[1], s.qn[2], s.qn[3], dR, dqn);
      const T dot = dqn[0] * s.qn[0] + dqn[1] * s.qn[1] + dqn[2] * s.qn[2] + dqn[3] * s.qn[3];
      for (int k = 0; k < 4; ++k) g.quats[4 * i + k] += (dqn[k] - s.qn[k] * dot) * s.qinv;

      // Jacobian rows J0 = (fx/z, 0, -fx tx/z^2), J1 = (0, fy/z, -fy ty/z^2), tx = z u_x
      const T z = s.p.z, iz = T(1) / z, iz2 = iz * iz;
      const T tx = z * s.u_x, ty = z * s.u_y;
      dpc.z += -cam.fx * iz2 * dJ0.x + T(2) * cam.fx * tx * iz2 * iz * dJ0.z;
      dpc.z += -cam.fy * iz2 * dJ1.y + T(2) * cam.fy * ty * iz2 * iz * dJ1.z;
      const T dtx = -cam.fx * iz2 * dJ0.z, dty = -cam.fy * iz2 * dJ1.z;
      if (s.clamped_x)
        dpc.z += s.u_x * dtx;
      else
        dpc.x += dtx;
      if (s.clamped_y)
        dpc.z += s.u_y * dty;
      else
        dpc.y += dty;

      // mean2d = (fx x/z + cx, fy y/z + cy)
      const T gmx = dp.mean2d[2 * i], gmy = dp.mean2d[2 * i + 1];
      dpc.x += cam.fx * iz * gmx;
      dpc.y += cam.fy * iz * gmy;
      dpc.z += -(cam.fx * s.p.x * gmx + cam.fy * s.p.y * gmy) * iz2;
      if (!dp.depth.empty()) dpc.z += dp.depth[i];  // depth = z

      // p = W mu + t
      dmu += glm::transpose(W) * dpc;
      dW += glm::outerProduct(dpc, mu);
      dt += dpc;
      for (int k = 0; k < 3; ++k) g.means[3 * i + k] += dmu[k];
    }
    dW_block[b] = dW;
    dt_block[b] = dt;
  }
  for (std::int64_t b = 0; b < blocks; ++b)
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) g.viewmat[r * 4 + c] += dW_block[b][c][r];
      g.viewmat[r * 4 + 3] += dt_block[b][r];
    }
}

template void project_forward<float>(const GaussianParams<float>&, const Camera<float>&,
                                     Projected<float>&);
template void project_forward<double>(const GaussianParams<double>&, const Camera<double>&,
                                      Projected<double>&);
template void project_backward<float>(const GaussianParams<float>&, const Camera<float>&,
                                      const Projected<float>&, const ProjectedGrads<float>&,
                                      ParamGrads<float>&);
template void project_backward<double>(const GaussianParams<double>&, const Camera<double>&,
                                       const Projected<double>&, const ProjectedGrads<double>&,
                                       ParamGrads<double>&);

}  // namespace spikegs::raster
