#include "core/spike_kernels.hpp"

#include <algorithm>
#if defined(__AVX512BW__)
#include <immintrin.h>
#endif
#include <cstring>
#include <type_traits>

#include "core/errors.hpp"

namespace spikegs {
namespace {

constexpr int64_t kChunkWords = 64;               // uint64 words of a frame per task
constexpr int64_t kChunkBits = kChunkWords * 64;  // 4096 pixels
constexpr int64_t kLaneWords = 8;                 // words counted together (one 512-bit vector)
// kLaneWords words as one vector (GCC/Clang vector extension, lowered to the target's SIMD).
using Lanes = uint64_t __attribute__((vector_size(8 * kLaneWords)));
constexpr int kMaxPlanes = 8;  // bit-sliced counters count up to 255
constexpr int64_t kMaxBlock = (1 << kMaxPlanes) - 1;

// The bytes [byte0, byte0 + nbytes) of every frame that one task handles.
struct Chunk {
  int64_t byte0, nbytes;
  int64_t full_words() const { return nbytes / 8; }
  int64_t words() const { return (nbytes + 7) / 8; }
  int64_t bit0() const { return byte0 * 8; }
  // Word j of this chunk in a frame; the partial last word is zero-padded, never read past.
  uint64_t word(const uint8_t* frame, int64_t j) const {
    uint64_t x = 0;
    std::memcpy(&x, frame + byte0 + 8 * j, size_t(std::min<int64_t>(8, nbytes - 8 * j)));
    return x;
  }
};

Chunk chunk_of(const SpikeLayout& l, int64_t c) {
  const int64_t byte0 = c * (kChunkBits / 8);
  return {byte0, std::min(kChunkBits / 8, l.frame_bytes() - byte0)};
}

int64_t num_chunks(const SpikeLayout& l) {
  return (l.frame_bytes() + kChunkBits / 8 - 1) / (kChunkBits / 8);
}

// Calls fn(r, x0, x1, i0) for each run of image pixels (r, x0..x1-1) stored in the chunk, where i0
// is the chunk-relative bit of (r, x0).
template <typename Fn>
void for_each_run(const SpikeLayout& l, const Chunk& c, Fn&& fn) {
  const int64_t p0 = c.bit0(), p1 = std::min(p0 + c.nbytes * 8, l.frame_bits());
  for (int64_t sr = p0 / l.row_bits; sr * l.row_bits < p1; ++sr) {
    const int64_t first = sr * l.row_bits + l.col_offset;  // bit of image column 0
    const int64_t x0 = std::max<int64_t>(0, p0 - first), x1 = std::min(l.width, p1 - first);
    if (x0 < x1) fn(l.stored_row(sr), x0, x1, first + x0 - p0);
  }
}

// Counts spikes over readouts [t0, t0 + len) for the chunk's words [j0, j0 + kLaneWords) into P
// bit-sliced counters: planes[q][j] holds bit q of the counts of the 64 pixels of word j. The
// counters of one group stay in registers (one 512-bit vector per plane) across all readouts.
// kWhole: the group lies in the chunk's whole words (plain loads); else words are zero-padded.
template <int P, bool kWhole>
void count_group(const PackedStream& s, int64_t t0, int64_t len, const Chunk& c, int64_t j0,
                 uint64_t (*planes)[kChunkWords]) {
  Lanes acc[P] = {};
  for (int64_t t = t0; t < t0 + len; ++t) {
    const uint8_t* frame = s.frame(t);
    Lanes x = {};
    if constexpr (kWhole)
      std::memcpy(&x, frame + c.byte0 + 8 * j0, sizeof(Lanes));
    else
      for (int64_t l = 0; l < kLaneWords && j0 + l < c.words(); ++l) x[l] = c.word(frame, j0 + l);
    for (int q = 0; q < P; ++q) {
      const Lanes carry = acc[q] & x;
      acc[q] ^= x;
      x = carry;
    }
  }
  for (int q = 0; q < P; ++q) std::memcpy(&planes[q][j0], &acc[q], sizeof(Lanes));
}

// cnt[64j + b] += the P-bit count whose bit q is bit b of planes[q][j], for words j < words.
template <int P>
void add_counts(const uint64_t (*planes)[kChunkWords], int64_t words, int32_t* cnt) {
#if defined(__AVX512BW__)
  // Per word: one masked byte add per plane gives the 64 pixels' counts as bytes.
  for (int64_t j = 0; j < words; ++j) {
    __m512i bytes = _mm512_setzero_si512();
    for (int q = 0; q < P; ++q)
      bytes = _mm512_mask_add_epi8(bytes, __mmask64(planes[q][j]), bytes,
                                   _mm512_set1_epi8(char(1 << q)));
    uint8_t counts[64];
    _mm512_storeu_si512(counts, bytes);
    for (int b = 0; b < 64; ++b) cnt[64 * j + b] += counts[b];
  }
#else
  for (int64_t j = 0; j < words; ++j)
    for (int half = 0; half < 2; ++half) {
      uint32_t bits[P];
      for (int q = 0; q < P; ++q) bits[q] = uint32_t(planes[q][j] >> (32 * half));
      int32_t* dst = cnt + 64 * j + 32 * half;
      for (int b = 0; b < 32; ++b) {
        int32_t v = 0;
        for (int q = 0; q < P; ++q) v |= int32_t((bits[q] >> b) & 1u) << q;
        dst[b] += v;
      }
    }
#endif
}

// cnt[i] += spikes at chunk bit i over readouts [t0, t0 + len), len < 2^P.
template <int P>
void count_block(const PackedStream& s, int64_t t0, int64_t len, const Chunk& c, int32_t* cnt) {
  uint64_t planes[P][kChunkWords];
  for (int64_t j0 = 0; j0 < c.words(); j0 += kLaneWords) {
    if (j0 + kLaneWords <= c.full_words())
      count_group<P, true>(s, t0, len, c, j0, planes);
    else
      count_group<P, false>(s, t0, len, c, j0, planes);
  }
  add_counts<P>(planes, c.words(), cnt);
}

using CountBlockFn = void (*)(const PackedStream&, int64_t, int64_t, const Chunk&, int32_t*);
constexpr CountBlockFn kCountBlock[kMaxPlanes + 1] = {
    nullptr,        count_block<1>, count_block<2>, count_block<3>, count_block<4>,
    count_block<5>, count_block<6>, count_block<7>, count_block<8>};

int planes_for(int64_t len) {
  int p = 0;
  while ((int64_t(1) << p) <= len) ++p;
  return p;
}

// Chunk-relative distance to the nearest spike at t = k + sign·d, d in [d0, d_end), per bit; bits
// with no spike there (or no pixel) keep `none`. Stops once every pixel bit has been found.
void nearest_spike(const PackedStream& s, const Chunk& c, const uint64_t* valid, int64_t k,
                   int64_t sign, int64_t d0, int64_t d_end, int32_t none, int32_t* dist) {
  uint64_t found[kChunkWords];
  const int64_t words = c.words();
  int64_t open = 0;
  for (int64_t j = 0; j < words; ++j) {
    found[j] = ~valid[j];
    open += found[j] != ~uint64_t(0);
  }
  std::fill(dist, dist + words * 64, none);
  for (int64_t d = d0; d < d_end && open > 0; ++d) {
    const uint8_t* frame = s.frame(k + sign * d);
    for (int64_t j = 0; j < words; ++j) {
      if (found[j] == ~uint64_t(0)) continue;
      uint64_t fresh = c.word(frame, j) & ~found[j];
      if (!fresh) continue;
      found[j] |= fresh;
      open -= found[j] == ~uint64_t(0);
      for (; fresh; fresh &= fresh - 1) dist[64 * j + __builtin_ctzll(fresh)] = int32_t(d);
    }
  }
}

}  // namespace

void check_windows(const PackedStream& s, const int64_t* starts, int64_t num, int64_t w) {
  if (w < 1 || w > kMaxWindow) fail("window length expected in [1, ", kMaxWindow, "], found ", w);
  for (int64_t i = 0; i < num; ++i) check_range(s, starts[i], w);
}

template <typename Out>
void window_counts(const PackedStream& s, const int64_t* starts, int64_t num, int64_t w, Out* out) {
  check_windows(s, starts, num, w);
  const SpikeLayout& l = s.layout;
  const int64_t chunks = num_chunks(l), hw = l.height * l.width;
  const double inv_w = 1.0 / double(w);
#pragma omp parallel for schedule(dynamic, 4)
  for (int64_t task = 0; task < num * chunks; ++task) {
    const int64_t i = task / chunks;
    const Chunk c = chunk_of(l, task % chunks);
    int32_t cnt[kChunkBits] = {};
    for (int64_t t = starts[i]; t < starts[i] + w; t += kMaxBlock) {
      const int64_t len = std::min(kMaxBlock, starts[i] + w - t);
      kCountBlock[planes_for(len)](s, t, len, c, cnt);
    }
    Out* dst = out + i * hw;
    for_each_run(l, c, [&](int64_t r, int64_t x0, int64_t x1, int64_t i0) {
      for (int64_t x = x0; x < x1; ++x) {
        if constexpr (std::is_integral_v<Out>)
          dst[r * l.width + x] = cnt[i0 + x - x0];
        else  // in double, then rounded: counts / w correctly rounded (see the header)
          dst[r * l.width + x] = Out(double(cnt[i0 + x - x0]) * inv_w);
      }
    });
  }
}

template void window_counts<int32_t>(const PackedStream&, const int64_t*, int64_t, int64_t,
                                     int32_t*);
template void window_counts<float>(const PackedStream&, const int64_t*, int64_t, int64_t, float*);

void check_tfi(const PackedStream& s, const int64_t* ks, int64_t num, int64_t max_interval) {
  if (max_interval < 1 || max_interval > kTfiMaxInterval)
    fail("max_interval expected in [1, ", kTfiMaxInterval, "], found ", max_interval);
  for (int64_t i = 0; i < num; ++i)
    if (ks[i] < 0 || ks[i] >= s.num_frames)
      fail("TFI readout expected in [0, ", s.num_frames, "), found ", ks[i]);
}

void tfi(const PackedStream& s, const int64_t* ks, int64_t num, int64_t max_interval, float* out) {
  check_tfi(s, ks, num, max_interval);
  const SpikeLayout& l = s.layout;
  const int64_t chunks = num_chunks(l), hw = l.height * l.width, M = max_interval;
#pragma omp parallel for schedule(dynamic, 4)
  for (int64_t task = 0; task < num * chunks; ++task) {
    const int64_t i = task / chunks, k = ks[i];
    const Chunk c = chunk_of(l, task % chunks);
    uint64_t valid[kChunkWords] = {};
    for_each_run(l, c, [&](int64_t, int64_t x0, int64_t x1, int64_t i0) {
      for (int64_t b = i0; b < i0 + (x1 - x0); ++b) valid[b >> 6] |= uint64_t(1) << (b & 63);
    });
    int32_t prev[kChunkBits], next[kChunkBits];
    nearest_spike(s, c, valid, k, -1, 0, std::min(k + 1, M), int32_t(M), prev);
    nearest_spike(s, c, valid, k, +1, 1, std::min(s.num_frames - k, M), int32_t(M), next);
    float* dst = out + i * hw;
    for_each_run(l, c, [&](int64_t r, int64_t x0, int64_t x1, int64_t i0) {
      for (int64_t x = x0; x < x1; ++x) {
        const int64_t b = i0 + x - x0;
        // In double: -ffast-math turns a float division into an approximate reciprocal.
        dst[r * l.width + x] =
            float(1.0 / double(std::min<int64_t>(int64_t(prev[b]) + next[b], M)));
      }
    });
  }
}

}  // namespace spikegs
