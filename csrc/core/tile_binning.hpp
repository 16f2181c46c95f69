// Tile binning: per-tile lists of visible Gaussians in front-to-back order, without a comparison
// sort: a radix sort by depth, then a counting pass by tile in that order.
#pragma once
#include <cstdint>
#include <vector>

#include "core/raster_types.hpp"

namespace spikegs::raster {

struct TileBins {
  int tiles_x = 0, tiles_y = 0;
  std::vector<std::int32_t> order;    // [V] Gaussian index of each depth rank (visible only)
  std::vector<std::int64_t> offsets;  // [tiles + 1] start of each tile's list in `ranks`
  std::vector<std::int32_t> ranks;    // [pairs] depth ranks, ascending within each tile
};

// Stable: equal depths keep Gaussian index order.
template <typename T>
void bin_tiles(const Projected<T>& proj, const Camera<T>& cam, TileBins& bins);

}  // namespace spikegs::raster
