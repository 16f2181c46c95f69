// Spike-stream core: layouts round trip, window counts and TFI against naive loops, simulator.
#include <algorithm>
#include <bitset>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/spike_format.hpp"
#include "core/spike_kernels.hpp"
#include "core/spike_rng.hpp"
#include "core/spike_simulator.hpp"
#include "harness.hpp"

using namespace spikegs;

namespace {

using Bits = std::vector<uint8_t>;  // [T, H, W] 0/1

Bits random_bits(int64_t T, int64_t H, int64_t W, double p, unsigned seed) {
  std::mt19937 gen(seed);
  std::bernoulli_distribution spike(p);
  Bits b(size_t(T * H * W));
  for (auto& v : b) v = spike(gen);
  return b;
}

// A packed copy of `bits` in `layout`, and the stream over it.
struct Packed {
  std::vector<uint8_t> bytes;
  PackedStream stream;
  Packed(const Bits& bits, int64_t T, const SpikeLayout& layout)
      : bytes(size_t(T * layout.frame_bytes())) {
    pack_frames(bits.data(), T, layout, bytes.data());
    stream = PackedStream::over(bytes.data(), int64_t(bytes.size()), layout);
  }
};

template <typename Fn>
bool throws_invalid(Fn&& fn) {
  try {
    fn();
  } catch (const std::invalid_argument&) {
    return true;
  }
  return false;
}

// Naive TFI at k for one pixel's spike train s[0..T), as documented in spike_kernels.hpp.
float naive_tfi(const std::vector<int>& s, int64_t k, int64_t M) {
  int64_t prev = -1, next = -1;
  for (int64_t t = k; t >= 0 && prev < 0; --t)
    if (s[t]) prev = t;
  for (int64_t t = k + 1; t < int64_t(s.size()) && next < 0; ++t)
    if (s[t]) next = t;
  const int64_t interval = (prev < 0 || next < 0) ? M : std::min(next - prev, M);
  return 1.0f / float(interval);
}

// The model of spike_simulator.hpp in double, one pixel at a time from readout 0, drawn from the
// simulator's random streams: frames [F, H, W] at `times` [F]; out [T, H, W] 0/1.
Bits reference_spikes(int64_t H, int64_t W, const SimParams& p, uint64_t seed,
                      const std::vector<float>& frames, const std::vector<double>& times,
                      int64_t T) {
  const int64_t hw = H * W, F = int64_t(times.size());
  const uint64_t pixel_key = mix64(seed ^ kPixelStream), key = mix64(seed ^ kReadoutStream);
  Bits out(size_t(T * hw));
  for (int64_t i = 0; i < hw; ++i) {
    const NormalPair c = normal_pair(spikegs::random_bits(pixel_key, 2 * uint64_t(i)));
    const double theta_i = p.threshold * std::max(1.0 + p.fpn_sigma * c.z0, 0.1);
    const double ds = p.dark_sigma, dark = p.dark_rate * std::exp(ds * c.z1 - ds * ds / 2);
    const double u = uniform_open(uint32_t(spikegs::random_bits(pixel_key, 2 * uint64_t(i) + 1)));
    double v = p.random_init ? u * theta_i : 0.0;
    for (int64_t t = 0, f = 0; t < T; ++t) {
      while (f + 1 < F && times[f + 1] <= double(t)) ++f;
      const double i0 = frames[f * hw + i];
      const double light = f + 1 < F ? i0 + (double(t) - times[f]) / (times[f + 1] - times[f]) *
                                                (frames[(f + 1) * hw + i] - i0)
                                     : i0;
      const double mu = p.threshold * (p.rate_at_one * std::max(light, 0.0) + dark);
      const NormalPair z = normal_pair(spikegs::random_bits(key, uint64_t(t * hw + i)));
      v += mu + (p.shot_noise ? std::sqrt(mu) * z.z0 : 0.0);
      const bool fire = v >= theta_i * std::max(1.0 + p.temporal_sigma * z.z1, 0.1);
      if (fire) v = std::min(v - theta_i, theta_i);
      out[t * hw + i] = fire;
    }
  }
  return out;
}

}  // namespace

TEST_CASE(round_trip_layouts) {
  for (int64_t W : {1, 7, 8, 13, 64, 400})
    for (bool flip : {false, true}) {
      const int64_t T = 5, H = 3;
      const Bits bits = random_bits(T, H, W, 0.4, unsigned(W));
      for (const SpikeLayout& l : {SpikeLayout::memory(H, W), SpikeLayout::dat(H, W, flip),
                                   SpikeLayout::dat(H, W, flip, W + 19, 5)}) {
        Packed p(bits, T, l);
        Bits back(bits.size());
        unpack_frames(p.stream, 0, T, back.data());
        CHECK(back == bits, "W=", W, " flip=", flip, " row_bits=", l.row_bits);
        // Through another layout and back.
        const SpikeLayout mem = SpikeLayout::memory(H, W);
        std::vector<uint8_t> re(size_t(T * mem.frame_bytes()));
        const Packed in_memory(bits, T, mem);
        repack_frames(p.stream, 0, T, mem, re.data());
        CHECK(re == in_memory.bytes, "repack W=", W, " flip=", flip);
        // and from memory into this layout, whose rows need not start on a byte
        std::vector<uint8_t> out(p.bytes.size());
        repack_frames(in_memory.stream, 0, T, l, out.data());
        CHECK(out == p.bytes, "repack into W=", W, " flip=", flip, " row_bits=", l.row_bits);
      }
    }
}

TEST_CASE(dat_layout_matches_camera_format) {
  // 2x8 frame, flipped: image row 1 is stored first, LSB = column 0.
  const Bits bits = {1, 0, 0, 0, 0, 0, 0, 1,   // image row 0
                     0, 1, 1, 0, 0, 0, 0, 0};  // image row 1
  Packed p(bits, 1, SpikeLayout::dat(2, 8, true));
  CHECK(p.bytes.size() == 2 && p.bytes[0] == 0x06 && p.bytes[1] == 0x81);
  // H·W not a multiple of 8: rows are bit-contiguous, the frame rounds up to whole bytes.
  CHECK(SpikeLayout::dat(3, 5, false).frame_bytes() == 2);
}

TEST_CASE(bad_shapes_refused) {
  std::vector<uint8_t> bytes(100);
  const SpikeLayout l = SpikeLayout::dat(4, 8, true);  // 4-byte frames
  CHECK(throws_invalid([&] { PackedStream::over(bytes.data(), 99, l); }), "truncated file");
  CHECK(!throws_invalid([&] { PackedStream::over(bytes.data(), 100, l); }));
  CHECK(throws_invalid([&] { SpikeLayout::dat(4, 8, true, 6); }), "raw row narrower than image");
  CHECK(throws_invalid([&] { SpikeLayout::memory(0, 8); }));
  // sizes whose arithmetic passed int64 (undefined; wrapped into a negative row that validate's
  // own check, overflowing too, let through)
  const int64_t max = std::numeric_limits<int64_t>::max();
  for (int64_t width : {max, max - 6})
    CHECK(throws_invalid([&] { SpikeLayout::memory(1, width); }), "width ", width);
  CHECK(throws_invalid([&] { SpikeLayout::dat(1, 8, false, -max); }), "a negative raw row");
  const PackedStream s = PackedStream::over(bytes.data(), 100, l);  // 25 readouts
  std::vector<int32_t> out(32);
  for (int64_t start : {-1, 23}) {
    CHECK(throws_invalid([&] { window_counts<int32_t>(s, &start, 1, 3, out.data()); }),
          "window start ", start);
  }
  std::vector<float> f(32);
  for (int64_t k : {-1, 25}) CHECK(throws_invalid([&] { tfi(s, &k, 1, 8, f.data()); }), "k=", k);
  std::vector<uint8_t> u(32 * 3);
  CHECK(throws_invalid([&] { unpack_frames(s, 23, 3, u.data()); }));
  // A window past int32's counts, in a stream that long (said to be: refused before any read).
  const PackedStream huge =
      PackedStream::over(bytes.data(), kMaxWindow + 1, SpikeLayout::dat(1, 8, false));
  const int64_t first = 0;
  CHECK(
      throws_invalid([&] { window_counts<int32_t>(huge, &first, 1, kMaxWindow + 1, out.data()); }),
      "a window of 2^31 readouts");
}

// Each check of a layout's and a kernel's arguments: what it lets through reads or writes past a
// frame (a negative or too wide crop, a frame past 2^63 bits, a repack into another image size) or
// divides by zero (a window of no readouts, a TFI bound below 1).
TEST_CASE(bad_arguments_refused) {
  CHECK(throws_invalid([&] { SpikeLayout::dat(4, 8, false, 16, -1); }), "a negative column offset");
  CHECK(throws_invalid([&] { SpikeLayout::dat(4, 8, false, 10, 3); }), "a crop past the row");
  CHECK(!throws_invalid([&] { SpikeLayout::dat(4, 8, false, 10, 2); }), "a crop to the row's end");
  CHECK(throws_invalid([&] { SpikeLayout::dat(int64_t(1) << 40, int64_t(1) << 30, false); }),
        "a frame of 2^70 bits");
  // bits within 7 of int64's end: rounding them up to whole bytes passes it
  const int64_t max = std::numeric_limits<int64_t>::max();
  CHECK(throws_invalid([&] { SpikeLayout::dat(1, max - 3, false); }), "a frame of 2^63 - 4 bits");
  std::vector<uint8_t> bytes(100);
  const PackedStream s = PackedStream::over(bytes.data(), 100, SpikeLayout::dat(4, 8, true));
  std::vector<uint8_t> out(100);
  CHECK(throws_invalid([&] { unpack_frames(s, 0, -1, out.data()); }), "a negative count");
  CHECK(throws_invalid([&] { repack_frames(s, 0, 1, SpikeLayout::memory(4, 9), out.data()); }),
        "a repack into another width");
  CHECK(throws_invalid([&] { repack_frames(s, 0, 1, SpikeLayout::memory(5, 8), out.data()); }),
        "a repack into another height");
  const int64_t start = 0;
  std::vector<float> f(32);
  CHECK(throws_invalid([&] { window_counts<float>(s, &start, 1, 0, f.data()); }), "a window of 0");
  for (int64_t m : {int64_t(0), kTfiMaxInterval + 1})
    CHECK(throws_invalid([&] { tfi(s, &start, 1, m, f.data()); }), "max_interval ", m);
  CHECK(!throws_invalid([&] { tfi(s, &start, 1, kTfiMaxInterval, f.data()); }));
}

TEST_CASE(window_counts_match_naive) {
  // A small cropped unaligned frame (one partial chunk), a 40x400 one (four chunks, the last
  // with a partial group of words), a cropped, flipped one of three chunks (chunks that start
  // and end in a stored row's margins) and one of 60 bytes (a group of 8 words, the last partial:
  // a whole group's load read 4 bytes past the stream's end, found under AddressSanitizer).
  const int64_t T = 700;
  for (const SpikeLayout& l :
       {SpikeLayout::dat(5, 123, true, 130, 3), SpikeLayout::memory(40, 400),
        SpikeLayout::dat(30, 150, true, 400, 200), SpikeLayout::memory(5, 96)}) {
    const int64_t H = l.height, W = l.width;
    const Bits bits = random_bits(T, H, W, 0.3, 7);
    Packed p(bits, T, l);
    // 1-31 readouts: counters of one to five bit planes; 255 and more: blocks of 255
    for (int64_t w : {1, 2, 3, 5, 9, 17, 33, 255, 256, 600}) {
      const std::vector<int64_t> starts = {0, 17, T - w};
      std::vector<int32_t> got(starts.size() * H * W);
      std::vector<float> tfp(got.size());
      window_counts<int32_t>(p.stream, starts.data(), int64_t(starts.size()), w, got.data());
      window_counts<float>(p.stream, starts.data(), int64_t(starts.size()), w, tfp.data());
      int bad = 0;
      for (size_t b = 0; b < starts.size(); ++b)
        for (int64_t i = 0; i < H * W; ++i) {
          int32_t want = 0;
          for (int64_t t = starts[b]; t < starts[b] + w; ++t) want += bits[t * H * W + i];
          const size_t o = b * H * W + i;
          bad += got[o] != want || tfp[o] != float(want) / float(w);  // correctly rounded
        }
      CHECK(bad == 0, H, "x", W, " w=", w, " mismatches=", bad);
    }
  }
}

// A spike every readout is a TFP of exactly 1 (41 · float(1/41) is not; nor 47, 55, 61, 82); and
// a count of w in every bit plane of its counters (windows of 1, 3, 7, 15, 31 readouts fill one to
// five planes).
TEST_CASE(window_counts_all_zero_all_one) {
  const int64_t T = 100, H = 4, W = 77;
  for (uint8_t value : {0, 1}) {
    Packed p(Bits(size_t(T * H * W), value), T, SpikeLayout::memory(H, W));
    const int64_t start = 3;
    for (int64_t w : {1, 3, 7, 15, 31, 33, 41, 47, 55, 61, 82}) {
      std::vector<float> tfp(H * W, -1.0f);
      window_counts<float>(p.stream, &start, 1, w, tfp.data());
      bool ok = true;
      for (float v : tfp) ok = ok && v == float(value);
      CHECK(ok, "value ", int(value), " w=", w);
    }
  }
}

TEST_CASE(tfi_matches_naive) {
  const int64_t T = 300, M = 50;
  for (const SpikeLayout& l : {SpikeLayout::dat(3, 70, true), SpikeLayout::memory(20, 400),
                               SpikeLayout::dat(30, 150, true, 400, 200)}) {
    const int64_t H = l.height, W = l.width;
    const Bits bits = random_bits(T, H, W, 0.02, 11);
    Packed p(bits, T, l);
    const std::vector<int64_t> ks = {0, 1, 100, 250, T - 1};
    std::vector<float> got(ks.size() * H * W);
    tfi(p.stream, ks.data(), int64_t(ks.size()), M, got.data());
    int bad = 0;
    for (int64_t i = 0; i < H * W; ++i) {
      std::vector<int> s(T);
      for (int64_t t = 0; t < T; ++t) s[t] = bits[t * H * W + i];
      for (size_t b = 0; b < ks.size(); ++b) bad += got[b * H * W + i] != naive_tfi(s, ks[b], M);
    }
    CHECK(bad == 0, H, "x", W, " mismatches=", bad);
  }
}

TEST_CASE(tfi_edge_cases) {
  // One pixel: spikes at readouts 0 and 4, nothing else in 10 readouts.
  Bits bits(10, 0);
  bits[0] = bits[4] = 1;
  Packed p(bits, 10, SpikeLayout::memory(1, 1));
  auto at = [&](int64_t k, int64_t M) {
    float v = -1;
    tfi(p.stream, &k, 1, M, &v);
    return v;
  };
  CHECK(at(0, 100) == 0.25f, "a spike at readout 0 counts as the last spike at k=0");
  CHECK(at(3, 100) == 0.25f);
  CHECK(at(4, 100) == 0.01f, "no spike after readout 4: 1/max_interval");
  CHECK(at(9, 100) == 0.01f, "last readout: 1/max_interval");
  CHECK(at(2, 3) == 1.0f / 3, "interval 4 capped at max_interval 3");
  // the next spike at the stream's last readout is found
  Bits ends(10, 0);
  ends[0] = ends[9] = 1;
  Packed last(ends, 10, SpikeLayout::memory(1, 1));
  const int64_t mid = 5;
  float w = -1;
  tfi(last.stream, &mid, 1, 100, &w);
  CHECK(w == 1.0f / 9, "spikes at readouts 0 and 9: TFI 1/9 at readout 5, found ", w);
  Packed none(Bits(10, 0), 10, SpikeLayout::memory(1, 1));
  const int64_t k = 5;
  float v = -1;
  tfi(none.stream, &k, 1, 7, &v);
  CHECK(v == 1.0f / 7, "no spike at all: 1/max_interval, found ", v);
  Packed all(Bits(10, 1), 10, SpikeLayout::memory(1, 1));
  tfi(all.stream, &k, 1, 7, &v);
  CHECK(v == 1.0f, "a spike every readout: TFI 1, found ", v);
}

TEST_CASE(simulator_independent_of_threads_and_chunks) {
  const int64_t H = 9, W = 21, T = 60;
  const std::vector<float> frames(2 * H * W, 0.7f);
  const std::vector<double> times = {0.0, double(T - 1)};
  auto simulate = [&](int threads, int64_t chunk) {
    harness::set_threads(threads);
    SpikeSimulator sim(H, W, SimParams{}, 1234);
    std::vector<uint8_t> out(size_t(T * H * ((W + 7) / 8)));
    for (int64_t t = 0; t < T; t += chunk)
      sim.run(frames.data(), times.data(), 2, std::min(chunk, T - t),
              out.data() + t * H * ((W + 7) / 8));
    return out;
  };
  const auto a = simulate(1, T), b = simulate(2, 7);
  harness::set_threads(0);
  CHECK(a == b, "same seed, other thread count and chunking");
  SpikeSimulator other(H, W, SimParams{}, 1235);
  std::vector<uint8_t> c(a.size());
  other.run(frames.data(), times.data(), 2, T, c.data());
  CHECK(a != c, "another seed gives another stream");
}

TEST_CASE(simulator_refuses_bad_input) {
  SimParams bad;
  bad.rate_at_one = 1.5;
  CHECK(throws_invalid([&] { SpikeSimulator(2, 2, bad, 0); }));
  // infinities too, under -ffast-math (which folds std::isfinite to true)
  const double inf = std::numeric_limits<double>::infinity();
  for (double SimParams::* field : {&SimParams::threshold, &SimParams::dark_sigma,
                                    &SimParams::fpn_sigma, &SimParams::temporal_sigma}) {
    SimParams infinite;
    infinite.*field = inf;
    CHECK(throws_invalid([&] { SpikeSimulator(2, 2, infinite, 0); }), "an infinite parameter");
  }
  // each parameter past either end of its range
  const std::pair<double SimParams::*, double> out_of_range[] = {
      {&SimParams::threshold, 9e-4}, {&SimParams::threshold, 1.1e30},
      {&SimParams::rate_at_one, 0},  {&SimParams::dark_rate, -1e-9},
      {&SimParams::dark_rate, 1.5},  {&SimParams::dark_sigma, -0.1},
      {&SimParams::fpn_sigma, -0.1}, {&SimParams::temporal_sigma, -0.1}};
  for (const auto& [field, value] : out_of_range) {
    SimParams params;
    params.*field = value;
    CHECK(throws_invalid([&] { SpikeSimulator(2, 2, params, 0); }), "a parameter of ", value);
  }
  // and each end of a closed range accepted
  const std::pair<double SimParams::*, double> range_ends[] = {{&SimParams::threshold, 1e-3},
                                                               {&SimParams::threshold, 1e30},
                                                               {&SimParams::rate_at_one, 1.0},
                                                               {&SimParams::dark_rate, 1.0}};
  for (const auto& [field, value] : range_ends) {
    SimParams params;
    params.*field = value;
    CHECK(!throws_invalid([&] { SpikeSimulator(2, 2, params, 0); }), "a parameter of ", value);
  }
  CHECK(throws_invalid([&] { SpikeSimulator(2, 0, SimParams{}, 0); }), "a width of 0");
  // height x width past int64 (undefined: an optimised build wrote into an empty simulator)
  CHECK(throws_invalid([&] { SpikeSimulator(int64_t(1) << 32, int64_t(1) << 32, SimParams{}, 0); }),
        "2^64 pixels");
  SpikeSimulator sim(2, 2, SimParams{}, 0);
  const std::vector<float> frames(8, 0.5f);
  const std::vector<double> short_times = {0.0, 5.0}, unsorted = {3.0, 1.0};
  std::vector<uint8_t> out(20);
  CHECK(throws_invalid([&] { sim.run(frames.data(), short_times.data(), 2, 10, out.data()); }),
        "frames must cover every readout");
  CHECK(throws_invalid([&] { sim.run(frames.data(), unsorted.data(), 2, 1, out.data()); }));
  const std::vector<double> equal = {0.0, 0.0};
  CHECK(throws_invalid([&] { sim.run(frames.data(), equal.data(), 2, 1, out.data()); }),
        "two frames at one time");
  const std::vector<double> one_short = {0.0, 8.0}, covering = {0.0, 9.0};
  CHECK(throws_invalid([&] { sim.run(frames.data(), one_short.data(), 2, 10, out.data()); }),
        "frames ending a readout before the last");
  CHECK(!throws_invalid([&] {
    SpikeSimulator(2, 2, SimParams{}, 0).run(frames.data(), covering.data(), 2, 10, out.data());
  }),
        "frames ending at the last readout");
  CHECK(throws_invalid([&] { sim.run(frames.data(), short_times.data(), 0, 1, out.data()); }),
        "no frame");
  CHECK(throws_invalid([&] { sim.run(frames.data(), short_times.data(), 2, -1, out.data()); }),
        "a negative number of readouts");
  const std::vector<double> infinite_times = {0.0, inf};
  CHECK(throws_invalid([&] { sim.run(frames.data(), infinite_times.data(), 2, 1, out.data()); }),
        "an infinite frame time");
}

TEST_CASE(simulator_rate_is_calibrated_and_capped) {
  const int64_t H = 4, W = 64, T = 4000;
  SimParams params;
  params.dark_rate = 0;
  // Row r: intensity 0.5·r (rate 0.125·r); row 3 overexposed (40 times the saturating light).
  std::vector<float> frames(2 * H * W);  // [2, H, W], the same light at both ends
  for (int64_t i = 0; i < 2 * H * W; ++i) {
    const int64_t r = (i / W) % H;
    frames[i] = r == 3 ? 160.0f : 0.5f * float(r);
  }
  const std::vector<double> times = {0.0, double(T - 1)};
  SpikeSimulator sim(H, W, params, 3);
  std::vector<uint8_t> packed(size_t(T * H * 8));
  sim.run(frames.data(), times.data(), 2, T, packed.data());
  const PackedStream s =
      PackedStream::over(packed.data(), int64_t(packed.size()), SpikeLayout::memory(H, W));
  const int64_t start = 0;
  std::vector<float> rate(H * W);
  window_counts<float>(s, &start, 1, T, rate.data());
  for (int64_t r = 0; r < 3; ++r) {
    double mean = 0;
    for (int64_t x = 0; x < W; ++x) mean += rate[r * W + x] / double(W);
    const double want = 0.25 * 0.5 * double(r);
    CHECK(std::abs(mean - want) < 0.01 * want + 1e-4, "row ", r, ": rate ", mean, " want ", want);
  }
  bool saturated = true;
  for (int64_t x = 0; x < W; ++x) saturated = saturated && rate[3 * W + x] == 1.0f;
  CHECK(saturated, "overexposed pixels fire once per readout, never more");
}

// The most light the simulator takes (saturated_light) saturates a pixel, which fires at its rate
// once the light falls; more is refused: up to float's largest was taken, θ · rate_at_one · I
// overflowed to inf above ~1.4e37, the voltage to NaN (inf - inf with shot noise, 0 · inf
// without), and the pixel never fired again.
TEST_CASE(simulator_survives_the_brightest_light) {
  const int64_t W = 64, T = 2000;
  for (const bool shot : {true, false}) {
    SimParams params;
    params.shot_noise = shot;
    SpikeSimulator sim(1, W, params, 11);
    const std::vector<float> bright(W, params.saturated_light()), one(W, 1.0f);
    const std::vector<double> at = {0.0};
    std::vector<uint8_t> lit(size_t(50 * 8)), after(size_t(T * 8));
    const float biggest = std::numeric_limits<float>::max();
    for (const float more : {std::nextafter(bright[0], biggest), biggest}) {
      std::vector<float> brighter = bright;
      brighter[W / 2] = more;
      CHECK(throws_invalid([&] { sim.run(brighter.data(), at.data(), 1, 50, lit.data()); }),
            "light of ", more, " taken");
    }
    sim.run(bright.data(), at.data(), 1, 50, lit.data());
    sim.run(one.data(), at.data(), 1, T, after.data());
    int64_t fired = 0, fired_after = 0;
    for (const uint8_t byte : lit) fired += int64_t(std::bitset<8>(byte).count());
    for (const uint8_t byte : after) fired_after += int64_t(std::bitset<8>(byte).count());
    CHECK(fired == 50 * W, "shot noise ", shot, ": ", fired, " of ", 50 * W, " readouts fired");
    const double rate = double(fired_after) / double(T * W);
    CHECK(std::abs(rate - 0.25) < 0.01, "shot noise ", shot, ": rate ", rate, " after, want 0.25");
  }
}

// A readout at exactly a frame's time sees that frame's light, not the previous frame's
// interpolated to weight 1: from a frame of 4e6 (the most light, saturated_light),
// 4e6 + (2.4 - 4e6) is 2.5 in float. Noise off, one pixel, θ = 100, 25 photo-electrons per unit
// of light: readout 0 fires and banks θ (the cap), readout 1 (light 2.4: 60 e) fires and keeps
// 60, readout 2 (1.55: 38.75 e more) does not fire; with 2.5 read at readout 1 it kept 62.5, and
// readout 2 fired.
TEST_CASE(simulator_readout_at_a_frame_time_sees_that_frame) {
  SimParams params;
  params.dark_rate = 0, params.dark_sigma = 0, params.fpn_sigma = 0, params.temporal_sigma = 0;
  params.shot_noise = false, params.random_init = false;
  const std::vector<float> frames = {params.saturated_light(), 2.4f, 1.55f};  // [3, 1, 1]
  const std::vector<double> times = {0.0, 1.0, 2.0};
  SpikeSimulator sim(1, 1, params, 5);
  std::vector<uint8_t> out(3, 0xff);
  sim.run(frames.data(), times.data(), 3, 3, out.data());
  CHECK(out[0] == 1 && out[1] == 1 && out[2] == 0, "spikes ", int(out[0]), int(out[1]), int(out[2]),
        ", expected 110");
  // the same readouts in two calls, the first ending at its last frame's time (a chunk's end),
  // which it read as frames[0] + 1 · (frames[1] - frames[0]): 2.5, and spikes 111
  SpikeSimulator split(1, 1, params, 5);
  std::vector<uint8_t> parts(3, 0xff);
  split.run(frames.data(), times.data(), 2, 2, parts.data());
  split.run(frames.data() + 1, times.data() + 1, 2, 1, parts.data() + 2);
  CHECK(parts == out, "spikes in two calls ", int(parts[0]), int(parts[1]), int(parts[2]),
        ", expected 110");
}

// The simulator against its model in double (reference_spikes), with every noise on and large, in
// calls of 1 to 63 readouts, and with the noises and the random start off. A draw taken from the
// wrong stream or normal (the threshold noise from the shot noise's), the nominal threshold for a
// pixel's own, or a readout count not advanced changes most pixels' trains. Float against
// double may flip a decision within rounding of the threshold: up to 1 % of the pixels may differ.
TEST_CASE(simulator_matches_its_model) {
  const int64_t H = 6, W = 45, T = 240, hw = H * W;
  std::vector<float> frames(3 * hw);  // [3, H, W] at readouts 0, 100, 239; some pixels dark
  for (int64_t i = 0; i < 3 * hw; ++i) frames[i] = float((i * 37) % 11) * 0.2f;
  const std::vector<double> times = {0.0, 100.0, 239.0};
  SimParams noisy;
  noisy.threshold = 40, noisy.rate_at_one = 0.3, noisy.dark_rate = 0.02, noisy.dark_sigma = 0.8;
  noisy.fpn_sigma = 0.2, noisy.temporal_sigma = 0.05;
  SimParams quiet;
  quiet.shot_noise = false, quiet.random_init = false;
  for (const SimParams& params : {noisy, quiet}) {
    SpikeSimulator sim(H, W, params, 77);
    const SpikeLayout l = SpikeLayout::memory(H, W);
    std::vector<uint8_t> packed(size_t(T * l.frame_bytes()));
    for (int64_t t = 0, call = 0; t < T; ++call) {
      const int64_t n = std::min<int64_t>(T - t, call % 2 == 0 ? 1 : 7 * call);
      sim.run(frames.data(), times.data(), 3, n, packed.data() + t * l.frame_bytes());
      t += n;
    }
    Bits got(size_t(T * hw));
    unpack_frames(PackedStream::over(packed.data(), int64_t(packed.size()), l), 0, T, got.data());
    const Bits want = reference_spikes(H, W, params, 77, frames, times, T);
    int64_t differ = 0, spikes = 0;
    for (int64_t i = 0; i < hw; ++i) {
      bool same = true;
      for (int64_t t = 0; t < T; ++t) {
        same = same && got[t * hw + i] == want[t * hw + i];
        spikes += want[t * hw + i];
      }
      differ += !same;
    }
    CHECK(differ * 100 <= hw, "pixels whose spikes differ from the model: ", differ, " of ", hw);
    CHECK(spikes > 10 * hw, "the model fired ", spikes, " spikes, expected more than 10 a pixel");
  }
}
