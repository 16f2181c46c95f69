// Kernels on packed spike streams, counting straight from the packed bits (no byte per pixel).
//
// Window counts: for each start s, count[r, x] = number of spikes in readouts [s, s+w). The frame
// is cut into chunks of 4096 bits (one OpenMP task per chunk and start); per chunk the w frames
// are summed with bit-sliced (vertical) counters: 512 pixels (8 words) at a time, one register per
// bit of the count, a ripple-carry add per frame. The planes become per-pixel counts once per
// window (with AVX-512BW one masked byte add per plane and 64 pixels), in blocks of 255 readouts.
// TFP = count / w. The frame's layout (flip, crop, unaligned rows) only matters when the counts
// are written out, so files are counted in place, memory-mapped.
//
// TFI at readout k, in 1/readouts:
//   TFI(k) = 1 / min(t_next - t_prev, max_interval)
//   t_prev = the last readout <= k with a spike (a spike at k itself, or at readout 0, counts),
//   t_next = the first readout > k with a spike,
// where a side with no spike in the stream is infinitely far. So a pixel with no spike within
// max_interval readouts around k reads 1/max_interval: never inf, NaN or a read past the stream;
// at the last readout there is no t_next and TFI = 1/max_interval. Interval >= 1, so TFI <= 1.
// The search is bounded: t_prev in [k - max_interval + 1, k], t_next in [k + 1, k + max_interval -
// 1].
#pragma once
#include <cstdint>

#include "core/spike_format.hpp"

namespace spikegs {

constexpr int64_t kTfiDefaultMaxInterval = 1024;
constexpr int64_t kTfiMaxInterval = int64_t(1) << 30;  // TFI's bound on max_interval
constexpr int64_t kMaxWindow = INT32_MAX;  // window_counts' bound on w: it counts in int32

// out [num, H, W] = spikes in readouts [starts[i], starts[i] + w) as int32_t counts, or as float
// counts / w (TFP), correctly rounded (a spike every readout gives exactly 1): the product with
// 1/w in double errs by < 3e-16 relatively, and counts / w with w < 2^24 lies at least 2^-49
// (relatively) from any point halfway between floats, so rounding to float picks the right one
// whatever -ffast-math does to a division (a window of 2^24 readouts or more, 7 minutes at 40 kHz,
// within an ulp). Each window must lie in the stream and w in [1, kMaxWindow]
// (std::invalid_argument otherwise).
template <typename Out>
void window_counts(const PackedStream& s, const int64_t* starts, int64_t num, int64_t w, Out* out);
// window_counts' checks of its arguments alone (a caller may check before allocating `out`)
void check_windows(const PackedStream& s, const int64_t* starts, int64_t num, int64_t w);

// out [num, H, W] = TFI at readouts ks[i] (each in [0, T)), defined above.
void tfi(const PackedStream& s, const int64_t* ks, int64_t num, int64_t max_interval, float* out);
// tfi's checks of its arguments alone
void check_tfi(const PackedStream& s, const int64_t* ks, int64_t num, int64_t max_interval);

}  // namespace spikegs
