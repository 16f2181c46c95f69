// Tile binning: per-tile lists of visible Gaussians in front-to-back order, without a comparison
// sort: a radix sort by depth, then a counting pass by tile in that order (parallel over runs of
// depth ranks; the lists do not depend on the thread count).
#pragma once
#include <cstdint>
#include <vector>

#include "core/raster_types.hpp"

namespace spikegs::raster {

struct TileBins {
  int tiles_x = 0, tiles_y = 0;
  std::vector<std::int32_t> order;    // [V] Gaussian index of each depth rank (visible only)
  std::vector<std::int32_t> rect;     // [V, 4] tile range of each depth rank (Projected::tile_rect)
  std::vector<std::int64_t> offsets;  // [tiles + 1] start of each tile's list in `ranks`
  std::vector<std::int32_t> ranks;    // [pairs] depth ranks, ascending within each tile
  // The same pairs listed by depth rank, each rank's tiles in row-major order (`rank_major`):
  // rank r's pairs are [rank_begin[r], rank_begin[r + 1]). The backward writes each pair's
  // gradient share to its own slot and sums a rank's slots in this order, so the sums do not
  // depend on how tiles are split among threads.
  std::vector<std::int64_t> rank_begin;  // [V + 1]
};

// Position, in the rank-major listing, of the pair (tile t, depth rank `rank`); the rank's tile
// range holds tile t.
inline std::int64_t rank_major(const TileBins& bins, std::int32_t rank, std::int64_t t) {
  const std::int32_t* rect = &bins.rect[4 * std::int64_t(rank)];
  const std::int64_t tx = t % bins.tiles_x, ty = t / bins.tiles_x;
  return bins.rank_begin[rank] + (ty - rect[1]) * (rect[2] - rect[0]) + (tx - rect[0]);
}

// Stable: equal depths keep Gaussian index order.
template <typename T>
void bin_tiles(const Projected<T>& proj, const Camera<T>& cam, TileBins& bins);

}  // namespace spikegs::raster
