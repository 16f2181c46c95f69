#include "core/tile_binning.hpp"

#include <array>
#include <cstring>
#include <type_traits>

namespace spikegs::raster {
namespace {

// LSD radix sort of `index` by `key` (unsigned), 8 bits a pass; passes where every key shares the
// digit are skipped. Stable.
template <typename Key>
void radix_sort(std::vector<Key>& key, std::vector<std::int32_t>& index) {
  const std::size_t n = key.size();
  std::vector<Key> key_tmp(n);
  std::vector<std::int32_t> index_tmp(n);
  for (unsigned shift = 0; shift < 8 * sizeof(Key); shift += 8) {
    std::array<std::size_t, 257> count{};
    for (std::size_t i = 0; i < n; ++i) ++count[((key[i] >> shift) & 0xff) + 1];
    bool trivial = false;
    for (int d = 1; d <= 256; ++d) trivial |= count[d] == n;
    if (trivial) continue;
    for (int d = 0; d < 256; ++d) count[d + 1] += count[d];
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t dst = count[(key[i] >> shift) & 0xff]++;
      key_tmp[dst] = key[i];
      index_tmp[dst] = index[i];
    }
    key.swap(key_tmp);
    index.swap(index_tmp);
  }
}

}  // namespace

template <typename T>
void bin_tiles(const Projected<T>& proj, const Camera<T>& cam, TileBins& bins) {
  using Key = std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>;
  const std::int64_t n = std::int64_t(proj.radius.size());
  bins.tiles_x = cam.tiles_x();
  bins.tiles_y = cam.tiles_y();
  const std::int64_t tiles = std::int64_t(bins.tiles_x) * bins.tiles_y;

  // Visible Gaussians keyed by depth: depth > near > 0, so the bit pattern orders like the value.
  std::vector<Key> key;
  bins.order.clear();
  for (std::int64_t i = 0; i < n; ++i) {
    if (proj.radius[i] == 0) continue;
    Key k;
    std::memcpy(&k, &proj.depth[i], sizeof k);
    key.push_back(k);
    bins.order.push_back(std::int32_t(i));
  }
  radix_sort(key, bins.order);

  // Count pairs per tile (and per rank), prefix-sum, then fill in depth order.
  bins.offsets.assign(tiles + 1, 0);
  bins.rank_begin.assign(1, 0);
  for (const std::int32_t i : bins.order) {
    const std::int32_t* r = &proj.tile_rect[4 * std::int64_t(i)];
    for (int ty = r[1]; ty < r[3]; ++ty)
      for (int tx = r[0]; tx < r[2]; ++tx) ++bins.offsets[std::int64_t(ty) * bins.tiles_x + tx + 1];
    bins.rank_begin.push_back(bins.rank_begin.back() + std::int64_t(r[2] - r[0]) * (r[3] - r[1]));
  }
  for (std::int64_t t = 0; t < tiles; ++t) bins.offsets[t + 1] += bins.offsets[t];
  bins.ranks.resize(bins.offsets[tiles]);
  std::vector<std::int64_t> cursor(bins.offsets.begin(), bins.offsets.end() - 1);
  for (std::int32_t rank = 0; rank < std::int32_t(bins.order.size()); ++rank) {
    const std::int32_t* r = &proj.tile_rect[4 * std::int64_t(bins.order[rank])];
    for (int ty = r[1]; ty < r[3]; ++ty)
      for (int tx = r[0]; tx < r[2]; ++tx)
        bins.ranks[cursor[std::int64_t(ty) * bins.tiles_x + tx]++] = rank;
  }
}

template void bin_tiles<float>(const Projected<float>&, const Camera<float>&, TileBins&);
template void bin_tiles<double>(const Projected<double>&, const Camera<double>&, TileBins&);

}  // namespace spikegs::raster
