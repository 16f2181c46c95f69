// Spike camera simulator: integrate-and-fire per pixel at the readout rate (τ = 25 µs).
//
// Units: intensity I is in firing-rate units (I = 1 fires rate_at_one spikes per readout) and the
// voltage is in photo-electrons. Per pixel i and readout t, with light I(t) linearly interpolated
// between the two rendered frames around t:
//   μ    = θ · (rate_at_one · max(I, 0) + dark_i)                    mean charge this readout
//   v   += μ + √μ · z₀            (shot_noise; else v += μ)           photon shot noise
//   θ_t  = θ_i · max(1 + temporal_sigma · z₁, 0.1)                   temporal threshold noise
//   spike if v >= θ_t, then v = min(v - θ_i, θ_i)                    reset by subtraction
// with z₀, z₁ standard normals, θ_i = θ · max(1 + fpn_sigma · z, 0.1) the pixel's threshold
// (fixed-pattern mismatch) and dark_i = dark_rate · exp(dark_sigma · z - dark_sigma²/2) its dark
// current (log-normal across pixels, mean dark_rate). v starts uniform in [0, θ_i) (random_init)
// or at 0. At most one spike per readout; the remainder carries over (capped at θ_i, so a
// saturated pixel fires every readout without banking charge). Charge is conserved, so a pixel's
// long-run rate is (rate_at_one · I + dark_i) · θ / θ_i: linear in I (to float's rounding: a
// readout's charge under ~2^-24 θ is lost against a voltage near θ, a rate under ~1e-7 spikes a
// readout without shot noise or dark current, 251 of 256 spikes at 1e-6).
// Shot noise uses the moment-matched normal form of the Poisson photon count (same mean and
// variance); the charge a spike integrates sums many readouts, where the two agree. Where a spike
// is a few photo-electrons (θ < 2, warned of in Python's SimParams) a readout's normal draw can
// overshoot the cap or go negative and the rate falls below linear (-1% at θ = 1, I = 1).
// Every draw comes from a counter-based generator keyed by the seed, the readout and the pixel:
// the output does not depend on the thread count or on how readouts are split between calls.
#pragma once
#include <cstdint>
#include <vector>

namespace spikegs {

// The simulator's random streams, each keyed mix64(seed ^ stream): pixel i's constants are
// normal_pair(random_bits(pixel key, 2i)) (threshold z0, dark current z1) and the uniform of
// random_bits(pixel key, 2i + 1) (initial voltage); readout t's draws at pixel i (of hw) are
// normal_pair(random_bits(readout key, t·hw + i)) (shot noise z0, threshold noise z1).
constexpr uint64_t kPixelStream = 0x5049584C5F434F4Eull;
constexpr uint64_t kReadoutStream = 0x524541444F555453ull;

struct SimParams {
  double threshold = 100.0;      // θ: photo-electrons per spike; shot noise of one spike ~ 1/√θ
  double rate_at_one = 0.25;     // spikes per readout at intensity 1.0 (the calibration knob)
  double dark_rate = 5e-4;       // mean dark-current spikes per readout (20 Hz at 40 kHz)
  double dark_sigma = 0.5;       // log-normal spread of the dark current across pixels
  double fpn_sigma = 0.03;       // fixed-pattern threshold mismatch, relative std
  double temporal_sigma = 0.01;  // threshold noise per readout, relative std
  bool shot_noise = true;        // photon shot noise on the integrated charge
  bool random_init = true;       // initial voltage uniform in [0, θ_i) rather than 0

  // Throws std::invalid_argument (expected vs found) for a value out of range.
  void validate() const;

  // The most light the simulator takes: a million times the light that fires every readout
  // fires every readout, as any more does, and its charge stays finite in float (above
  // FLT_MAX / (θ · rate_at_one), 1.4e37 at the defaults, it overflowed to a NaN voltage, and the
  // pixel never fired again). Callers cap their light at it (simulate_spikes does).
  float saturated_light() const;
};

class SpikeSimulator {
 public:
  SpikeSimulator(int64_t height, int64_t width, const SimParams& params, uint64_t seed);

  // Simulates the next n readouts, [r, r + n) where the calls so far simulated r, under the light
  // of frames [F, H, W] shown at readout times `times` [F] (strictly increasing, times[0] <= r,
  // times[F-1] >= the last readout), linearly interpolated in between, a readout at a frame's time
  // reading that frame exactly (the same light however readouts are split between calls); a single
  // frame (F = 1) is constant light. Writes out [n, H, ceil(W/8)] (memory layout).
  void run(const float* frames, const double* times, int64_t num_frames, int64_t n, uint8_t* out);

  int64_t height() const { return height_; }
  int64_t width() const { return width_; }

 private:
  int64_t height_, width_;
  SimParams params_;
  uint64_t key_;
  int64_t readout_ = 0;
  std::vector<float> voltage_;  // [H, W] photo-electrons
  std::vector<float> theta_;    // [H, W] per-pixel threshold θ_i
  std::vector<float> dark_;     // [H, W] dark charge per readout, θ · dark_i
};

}  // namespace spikegs
