#include "core/spike_format.hpp"

#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "core/errors.hpp"

namespace spikegs {
namespace {

inline int get_bit(const uint8_t* p, int64_t bit) { return (p[bit >> 3] >> (bit & 7)) & 1; }
inline void set_bit(uint8_t* p, int64_t bit) { p[bit >> 3] |= uint8_t(1u << (bit & 7)); }

// Copies n bits from src at bit src_bit to dst at bit dst_bit; the destination bits must be zero.
void copy_bits(const uint8_t* src, int64_t src_bit, uint8_t* dst, int64_t dst_bit, int64_t n) {
  int64_t done = 0;
  if ((src_bit & 7) == 0 && (dst_bit & 7) == 0) {
    done = n & ~int64_t(7);
    std::memcpy(dst + (dst_bit >> 3), src + (src_bit >> 3), size_t(done >> 3));
  }
  for (int64_t i = done; i < n; ++i)
    if (get_bit(src, src_bit + i)) set_bit(dst, dst_bit + i);
}

}  // namespace

void check_range(const PackedStream& s, int64_t t0, int64_t n) {
  if (n < 0 || t0 < 0 || t0 > s.num_frames - n)  // t0 + n could overflow
    fail(n, " readouts from ", t0, " expected within the stream's [0, ", s.num_frames, ")");
}

void SpikeLayout::validate() const {
  if (height < 1 || width < 1) fail("height and width expected >= 1, found ", height, "x", width);
  if (col_offset < 0) fail("column offset expected >= 0, found ", col_offset);
  // each comparison free of overflow: col_offset + width, or height * row_bits, may pass int64
  // (row_bits - width only once row_bits >= width >= 1)
  if (row_bits < width || col_offset > row_bits - width)
    fail("stored rows of at least col_offset + width pixels expected (col_offset ", col_offset,
         ", width ", width, "), found ", row_bits);
  if (row_bits > (std::numeric_limits<int64_t>::max() - 7) / height)
    fail("a frame of ", height, " rows of ", row_bits, " bits expected below 2^63 bits");
}

SpikeLayout SpikeLayout::memory(int64_t height, int64_t width) {
  // rows padded to whole bytes: width + 7 wrapped past int64 (a negative row) within 7 of 2^63
  if (width > std::numeric_limits<int64_t>::max() - 7)
    fail("width expected below 2^63 - 7, found ", width);
  SpikeLayout l{height, width, 8 * ((width + 7) / 8), 0, false};
  l.validate();
  return l;
}

SpikeLayout SpikeLayout::dat(int64_t height, int64_t width, bool flip, int64_t raw_width,
                             int64_t col_offset) {
  SpikeLayout l{height, width, raw_width == 0 ? width : raw_width, col_offset, flip};
  l.validate();
  return l;
}

PackedStream PackedStream::over(const uint8_t* data, int64_t num_bytes, const SpikeLayout& layout) {
  layout.validate();
  const int64_t fb = layout.frame_bytes();
  if (num_bytes % fb != 0)
    fail("a whole number of ", layout.height, "x", layout.row_bits, " frames of ", fb,
         " bytes expected, found ", num_bytes, " bytes (", num_bytes / fb, " frames and ",
         num_bytes % fb, " bytes over)");
  return PackedStream{data, num_bytes / fb, layout};
}

void unpack_frames(const PackedStream& s, int64_t t0, int64_t n, uint8_t* out) {
  check_range(s, t0, n);
  const SpikeLayout& l = s.layout;
  const int64_t H = l.height, W = l.width;
#pragma omp parallel for collapse(2) schedule(static)
  for (int64_t t = 0; t < n; ++t)
    for (int64_t r = 0; r < H; ++r) {
      const uint8_t* src = s.frame(t0 + t);
      const int64_t b0 = l.bit_of(r, 0);
      uint8_t* row = out + (t * H + r) * W;
      for (int64_t x = 0; x < W; ++x) row[x] = uint8_t(get_bit(src, b0 + x));
    }
}

void pack_frames(const uint8_t* bits, int64_t n, const SpikeLayout& layout, uint8_t* out) {
  layout.validate();
  const int64_t H = layout.height, W = layout.width, fb = layout.frame_bytes();
  std::memset(out, 0, size_t(n * fb));
  // Rows of one frame may share a byte (unaligned layouts): parallel over frames only.
#pragma omp parallel for schedule(static)
  for (int64_t t = 0; t < n; ++t)
    for (int64_t r = 0; r < H; ++r) {
      const uint8_t* row = bits + (t * H + r) * W;
      const int64_t b0 = layout.bit_of(r, 0);
      for (int64_t x = 0; x < W; ++x)
        if (row[x]) set_bit(out + t * fb, b0 + x);
    }
}

void repack_frames(const PackedStream& s, int64_t t0, int64_t n, const SpikeLayout& dst,
                   uint8_t* out) {
  check_range(s, t0, n);
  dst.validate();
  if (dst.height != s.layout.height || dst.width != s.layout.width)
    fail("destination layout of ", s.layout.height, "x", s.layout.width, " expected, found ",
         dst.height, "x", dst.width);
  const int64_t fb = dst.frame_bytes();
  std::memset(out, 0, size_t(n * fb));
#pragma omp parallel for schedule(static)
  for (int64_t t = 0; t < n; ++t)
    for (int64_t r = 0; r < dst.height; ++r)
      copy_bits(s.frame(t0 + t), s.layout.bit_of(r, 0), out + t * fb, dst.bit_of(r, 0), dst.width);
}

}  // namespace spikegs
