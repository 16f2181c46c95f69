#include "core/spike_simulator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "core/errors.hpp"
#include "core/finite.hpp"
#include "core/spike_rng.hpp"
#include "core/thread_buffers.hpp"

namespace spikegs {
namespace {

// Light at one readout: frames f and f+1 mixed with weight a on the second.
struct Segment {
  int64_t f;
  float a;
};

}  // namespace

void SimParams::validate() const {
  auto check = [](bool ok, const char* name, const char* expected, double found) {
    if (!ok) fail(name, " expected ", expected, ", found ", found);
  };
  // is_finite (bit-level): -ffast-math folds std::isfinite to true, letting inf through
  // voltages are float: a threshold near float's range (3.4e38) overflowed them, one near its
  // smallest normal (1.2e-38) rounded to 0 and fired every readout (a spike of less than a
  // thousandth of a photo-electron is no camera's)
  check(threshold >= 1e-3 && threshold <= 1e30 && is_finite(threshold), "threshold",
        "in [0.001, 1e30]", threshold);
  check(rate_at_one > 0 && rate_at_one <= 1, "rate_at_one", "in (0, 1]", rate_at_one);
  check(dark_rate >= 0 && dark_rate <= 1, "dark_rate", "in [0, 1]", dark_rate);
  check(dark_sigma >= 0 && is_finite(dark_sigma), "dark_sigma", "finite, >= 0", dark_sigma);
  check(fpn_sigma >= 0 && is_finite(fpn_sigma), "fpn_sigma", "finite, >= 0", fpn_sigma);
  check(temporal_sigma >= 0 && is_finite(temporal_sigma), "temporal_sigma", "finite, >= 0",
        temporal_sigma);
}

float SimParams::saturated_light() const {
  return float(std::min(1e6 / rate_at_one, double(std::numeric_limits<float>::max())));
}

SpikeSimulator::SpikeSimulator(int64_t height, int64_t width, const SimParams& params,
                               uint64_t seed)
    : height_(height), width_(width), params_(params), key_(mix64(seed ^ kReadoutStream)) {
  if (height < 1 || width < 1) fail("height and width expected >= 1, found ", height, "x", width);
  // the pixel count in int64: a product past 2^63 wrapped (undefined), and an optimised build
  // wrote into an empty simulator
  if (width > std::numeric_limits<int64_t>::max() / height)
    fail("height x width expected below 2^63 pixels, found ", height, "x", width);
  params.validate();
  const int64_t hw = height * width;
  voltage_.resize(size_t(hw));
  theta_.resize(size_t(hw));
  dark_.resize(size_t(hw));
  const uint64_t pixel_key = mix64(seed ^ kPixelStream);
  const double theta = params.threshold, ds = params.dark_sigma;
  for (int64_t i = 0; i < hw; ++i) {
    const NormalPair z = normal_pair(random_bits(pixel_key, 2 * uint64_t(i)));
    // float's largest where the spread overflows it: inf fired at readout 0, in the dark (the
    // initial voltage u·inf reached it), then never (inf - inf: a NaN voltage)
    theta_[i] = float(std::min(theta * std::max(1.0 + params.fpn_sigma * z.z0, 0.1),
                               double(std::numeric_limits<float>::max())));
    dark_[i] = float(theta * params.dark_rate * std::exp(ds * z.z1 - 0.5 * ds * ds));
    const float u = uniform_open(uint32_t(random_bits(pixel_key, 2 * uint64_t(i) + 1)));
    voltage_[i] = params.random_init ? u * theta_[i] : 0.0f;
  }
}

void SpikeSimulator::run(const float* frames, const double* times, int64_t num_frames, int64_t n,
                         uint8_t* out) {
  const int64_t t0 = readout_, last = readout_ + n - 1;
  if (n < 0) fail("number of readouts expected >= 0, found ", n);
  if (num_frames < 1) fail("at least one frame expected, found none");
  for (int64_t f = 0; f < num_frames; ++f)
    if (!is_finite(times[f]) || (f > 0 && !(times[f] > times[f - 1])))
      fail("frame times expected finite and strictly increasing, found ", times[f], " at frame ",
           f);
  // a NaN pixel would never fire again, nor one lit past saturated_light (its charge overflowed)
  const float most = params_.saturated_light();
  for (int64_t i = 0; i < num_frames * height_ * width_; ++i)
    if (!is_finite(frames[i]) || !(frames[i] >= 0.0f) || frames[i] > most)
      fail("frames expected intensities in [0, ", most,
           "] (saturated_light: any more fires every readout all the same), found ", frames[i],
           " at frame ", i / (height_ * width_), ", pixel ", i % (height_ * width_));
  if (num_frames > 1 && n > 0 && (times[0] > double(t0) || times[num_frames - 1] < double(last)))
    fail("frame times expected to cover readouts [", t0, ", ", last, "], found [", times[0], ", ",
         times[num_frames - 1], "]");

  // A readout at or past the last frame's time reads that frame alone (f = num_frames - 1, a = 0),
  // as a readout at any frame's time does: its light is then the same whichever frames follow in
  // this call. It was frames[F-2] + 1 · (frames[F-1] - frames[F-2]), which rounds (1 + (0.1 - 1)
  // is not 0.1 in float): a chunk of simulate_spikes ends on a frame's time whenever a frame is
  // rendered each readout, and the spikes differed with the chunk size.
  std::vector<Segment> seg(static_cast<size_t>(n));  // [n]
  for (int64_t t = 0, f = 0; t < n; ++t) {
    const double rt = double(t0 + t);
    while (f + 1 < num_frames && times[f + 1] <= rt) ++f;
    const bool last = f + 1 == num_frames;
    const double span = last ? 1.0 : times[f + 1] - times[f];
    seg[t] = {f, last ? 0.0f : float(std::clamp((rt - times[f]) / span, 0.0, 1.0))};
  }

  const int64_t H = height_, W = width_, hw = H * W, row_bytes = (W + 7) / 8;
  const float gain = float(params_.threshold * params_.rate_at_one);
  const float shot = params_.shot_noise ? 1.0f : 0.0f;
  const float tsig = float(params_.temporal_sigma);
  const uint64_t key = key_;
  ThreadBuffers<uint8_t> rows(static_cast<size_t>(8 * row_bytes));
#pragma omp parallel
  {
    uint8_t* const spike = rows.local();  // [8·ceil(W/8)] one row's spikes
#pragma omp for schedule(static)
    for (int64_t r = 0; r < H; ++r) {
      float* v = voltage_.data() + r * W;
      const float* theta = theta_.data() + r * W;
      const float* dark = dark_.data() + r * W;
      for (int64_t t = 0; t < n; ++t) {
        const float* i0 = frames + seg[t].f * hw + r * W;
        const float* i1 = seg[t].f + 1 < num_frames ? i0 + hw : i0;  // the last: a = 0
        const float a = seg[t].a;
        const uint64_t counter0 = uint64_t(t0 + t) * uint64_t(hw) + uint64_t(r * W);
#pragma omp simd
        for (int64_t x = 0; x < W; ++x) {
          const NormalPair z = normal_pair(random_bits(key, counter0 + uint64_t(x)));
          const float light = std::max(i0[x] + a * (i1[x] - i0[x]), 0.0f);
          const float mu = gain * light + dark[x];
          const float th = theta[x], vx = v[x] + mu + shot * std::sqrt(mu) * z.z0;
          const bool fire = vx >= th * std::max(1.0f + tsig * z.z1, 0.1f);
          v[x] = fire ? std::min(vx - th, th) : vx;
          spike[x] = fire;
        }
        uint8_t* row = out + (t * H + r) * row_bytes;
        for (int64_t j = 0; j < row_bytes; ++j) {
          uint8_t byte = 0;
          for (int b = 0; b < 8; ++b) byte |= uint8_t(spike[8 * j + b] << b);
          row[j] = byte;
        }
      }
    }
  }
  readout_ += n;
}

}  // namespace spikegs
