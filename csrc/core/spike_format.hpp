// Packed spike frames: where each pixel's bit lives, and decoding/encoding between layouts.
//
// A frame is H·row_bits bits stored contiguously, least significant bit first, rounded up to whole
// bytes. Image pixel (r, x) (r = 0 is the top row) is bit `bit_of(r, x)` of its frame:
//   stored_row = flip ? H-1-r : r,   bit = stored_row·row_bits + col_offset + x.
// Two layouts cover everything:
//   memory: [T, H, ceil(W/8)] uint8, row_bits = 8·ceil(W/8), unflipped (the in-memory convention);
//   .dat:   the spike camera file, row_bits = raw_width (W unless the camera stores extra columns),
//           flip = true for the readers of this family. A frame is ceil(H·raw_width/8) bytes, which
//           is the camera's H·W/8 whenever H·W is a multiple of 8.
#pragma once
#include <cstdint>

namespace spikegs {

struct SpikeLayout {
  int64_t height = 0;
  int64_t width = 0;
  int64_t row_bits = 0;    // bits per stored row, >= col_offset + width
  int64_t col_offset = 0;  // stored column of image column 0 (crops raw rows)
  bool flip = false;       // stored row 0 is the bottom image row

  int64_t frame_bits() const { return height * row_bits; }
  int64_t frame_bytes() const { return (frame_bits() + 7) / 8; }
  int64_t stored_row(int64_t r) const { return flip ? height - 1 - r : r; }
  int64_t bit_of(int64_t r, int64_t x) const { return stored_row(r) * row_bits + col_offset + x; }
  // Throws std::invalid_argument (expected vs found) for a shape that does not fit.
  void validate() const;

  static SpikeLayout memory(int64_t height, int64_t width);
  // raw_width = 0 means raw_width = width.
  static SpikeLayout dat(int64_t height, int64_t width, bool flip, int64_t raw_width = 0,
                         int64_t col_offset = 0);
};

// T frames of `layout.frame_bytes()` bytes each, back to back (a memory map or an array).
struct PackedStream {
  const uint8_t* data = nullptr;
  int64_t num_frames = 0;
  SpikeLayout layout;

  const uint8_t* frame(int64_t t) const { return data + t * layout.frame_bytes(); }
  // Builds a stream over `num_bytes` bytes; throws if that is not a whole number of frames.
  static PackedStream over(const uint8_t* data, int64_t num_bytes, const SpikeLayout& layout);
};

// std::invalid_argument unless readouts [t0, t0+n) lie in `s` (n >= 0; no overflow).
void check_range(const PackedStream& s, int64_t t0, int64_t n);
// Readouts [t0, t0+n) of `s` as 0/1 bytes: out [n, H, W].
void unpack_frames(const PackedStream& s, int64_t t0, int64_t n, uint8_t* out);
// bits [n, H, W] (nonzero = spike) into n frames of `layout` (padding bits zero): out [n,
// frame_bytes].
void pack_frames(const uint8_t* bits, int64_t n, const SpikeLayout& layout, uint8_t* out);
// Readouts [t0, t0+n) of `s` re-encoded in `dst` (same height and width): out [n, dst.frame_bytes].
void repack_frames(const PackedStream& s, int64_t t0, int64_t n, const SpikeLayout& dst,
                   uint8_t* out);

}  // namespace spikegs
