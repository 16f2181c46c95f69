// Real spherical harmonics of degree 0-3 (the 3DGS convention) and their gradients.
#pragma once

namespace spikegs::raster {

constexpr double kShC0 = 0.28209479177387814;
constexpr double kShC1 = 0.4886025119029199;
constexpr double kShC2[5] = {1.0925484305920792, -1.0925484305920792, 0.31539156525252005,
                             -1.0925484305920792, 0.5462742152960396};
constexpr double kShC3[7] = {-0.5900435899266435, 2.890611442640554,   -0.4570457994644658,
                             0.3731763325901154,  -0.4570457994644658, 1.445305721320277,
                             -0.5900435899266435};

// basis[k] = Y_k(d) for k < (degree + 1)^2, d a unit direction.
template <typename T>
void sh_basis(int degree, T x, T y, T z, T* basis) {
  basis[0] = T(kShC0);
  if (degree < 1) return;
  basis[1] = T(-kShC1) * y;
  basis[2] = T(kShC1) * z;
  basis[3] = T(-kShC1) * x;
  if (degree < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z;
  basis[4] = T(kShC2[0]) * x * y;
  basis[5] = T(kShC2[1]) * y * z;
  basis[6] = T(kShC2[2]) * (2 * zz - xx - yy);
  basis[7] = T(kShC2[3]) * x * z;
  basis[8] = T(kShC2[4]) * (xx - yy);
  if (degree < 3) return;
  basis[9] = T(kShC3[0]) * y * (3 * xx - yy);
  basis[10] = T(kShC3[1]) * x * y * z;
  basis[11] = T(kShC3[2]) * y * (4 * zz - xx - yy);
  basis[12] = T(kShC3[3]) * z * (2 * zz - 3 * xx - 3 * yy);
  basis[13] = T(kShC3[4]) * x * (4 * zz - xx - yy);
  basis[14] = T(kShC3[5]) * z * (xx - yy);
  basis[15] = T(kShC3[6]) * x * (xx - 3 * yy);
}

// grad += sum_k weight[k] * dY_k/d(x, y, z), with (x, y, z) treated as free variables.
template <typename T>
void sh_basis_vjp(int degree, T x, T y, T z, const T* weight, T grad[3]) {
  if (degree < 1) return;
  grad[1] += T(-kShC1) * weight[1];
  grad[2] += T(kShC1) * weight[2];
  grad[0] += T(-kShC1) * weight[3];
  if (degree < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z;
  auto add = [&](T w, T gx, T gy, T gz) {
    grad[0] += w * gx;
    grad[1] += w * gy;
    grad[2] += w * gz;
  };
  add(T(kShC2[0]) * weight[4], y, x, 0);
  add(T(kShC2[1]) * weight[5], 0, z, y);
  add(T(kShC2[2]) * weight[6], -2 * x, -2 * y, 4 * z);
  add(T(kShC2[3]) * weight[7], z, 0, x);
  add(T(kShC2[4]) * weight[8], 2 * x, -2 * y, 0);
  if (degree < 3) return;
  add(T(kShC3[0]) * weight[9], 6 * x * y, 3 * xx - 3 * yy, 0);
  add(T(kShC3[1]) * weight[10], y * z, x * z, x * y);
  add(T(kShC3[2]) * weight[11], -2 * x * y, 4 * zz - xx - 3 * yy, 8 * y * z);
  add(T(kShC3[3]) * weight[12], -6 * x * z, -6 * y * z, 6 * zz - 3 * xx - 3 * yy);
  add(T(kShC3[4]) * weight[13], 4 * zz - 3 * xx - yy, -2 * x * y, 8 * x * z);
  add(T(kShC3[5]) * weight[14], 2 * x * z, -2 * y * z, xx - yy);
  add(T(kShC3[6]) * weight[15], 3 * xx - 3 * yy, -6 * x * y, 0);
}

}  // namespace spikegs::raster
