#include "core/tile_binning.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <type_traits>

#include "core/thread_buffers.hpp"

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

  // Each rank's tile range, gathered once (read randomly by Gaussian, it was the cost of the
  // passes below), and its pair count, prefix-summed into rank_begin.
  const std::int64_t visible = std::int64_t(bins.order.size());
  bins.rect.resize(4 * visible);
  bins.rank_begin.resize(visible + 1);
  bins.rank_begin[0] = 0;
#pragma omp parallel for schedule(static) if (visible >= kParallelMinItems)
  for (std::int64_t rank = 0; rank < visible; ++rank) {
    const std::int32_t* r = &proj.tile_rect[4 * std::int64_t(bins.order[rank])];
    std::copy_n(r, 4, &bins.rect[4 * rank]);
    bins.rank_begin[rank + 1] = std::int64_t(r[2] - r[0]) * (r[3] - r[1]);
  }
  for (std::int64_t rank = 0; rank < visible; ++rank)
    bins.rank_begin[rank + 1] += bins.rank_begin[rank];

  // The ranks in `parts` runs of about equal pair counts: each run counts its pairs per tile, the
  // counts give each run its first slot in each tile's list, and each run fills its slots in
  // depth order. Runs follow depth order, so the lists are those of one serial pass whatever the
  // number of runs.
  const std::int64_t pairs = bins.rank_begin[visible];
  const std::int64_t parts =
      pairs >= kParallelMinItems ? std::min<std::int64_t>(max_threads(), visible) : 1;
  std::vector<std::int64_t> run_begin(parts + 1);  // [parts + 1] first rank of each run
  for (std::int64_t part = 0; part <= parts; ++part)
    run_begin[part] =
        std::lower_bound(bins.rank_begin.begin(), bins.rank_begin.end() - 1, pairs * part / parts) -
        bins.rank_begin.begin();
  std::vector<std::int64_t> cursor(parts * tiles, 0);  // [parts, tiles]
  const std::int64_t tiles_x = bins.tiles_x;
  auto run = [&](std::int64_t part, auto&& visit) {
    std::int64_t* c = &cursor[part * tiles];
    for (std::int64_t rank = run_begin[part]; rank < run_begin[part + 1]; ++rank) {
      // copied: the fill's stores into int32 `ranks` could alias the range
      const std::int64_t x0 = bins.rect[4 * rank], y0 = bins.rect[4 * rank + 1],
                         x1 = bins.rect[4 * rank + 2], y1 = bins.rect[4 * rank + 3];
      for (std::int64_t ty = y0; ty < y1; ++ty)
        for (std::int64_t t = ty * tiles_x + x0; t < ty * tiles_x + x1; ++t)
          visit(c[t], std::int32_t(rank));
    }
  };
#pragma omp parallel for schedule(static, 1) if (parts > 1)
  for (std::int64_t part = 0; part < parts; ++part)
    run(part, [](std::int64_t& count, std::int32_t) { ++count; });
  bins.offsets.resize(tiles + 1);
  bins.offsets[0] = 0;
  for (std::int64_t t = 0; t < tiles; ++t) {
    std::int64_t slot = bins.offsets[t];
    for (std::int64_t part = 0; part < parts; ++part) {
      const std::int64_t count = cursor[part * tiles + t];
      cursor[part * tiles + t] = slot;
      slot += count;
    }
    bins.offsets[t + 1] = slot;
  }
  bins.ranks.resize(bins.offsets[tiles]);
#pragma omp parallel for schedule(static, 1) if (parts > 1)
  for (std::int64_t part = 0; part < parts; ++part)
    run(part, [&](std::int64_t& slot, std::int32_t rank) { bins.ranks[slot++] = rank; });
}

template void bin_tiles<float>(const Projected<float>&, const Camera<float>&, TileBins&);
template void bin_tiles<double>(const Projected<double>&, const Camera<double>&, TileBins&);

}  // namespace spikegs::raster
