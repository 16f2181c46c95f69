// The rasterizer's outputs and gradients are bitwise the same whatever the OpenMP thread count:
// a run resumed or repeated on a machine with another core count follows the same path.
#include <cstdio>

#include "core/thread_buffers.hpp"
#include "harness.hpp"
#include "raster_scene.hpp"

using namespace test;

namespace {

struct Outcome {
  Render<float> render;
  Grads<float> grads;
};

// Renders and back-propagates `s` (in float, training's precision) with `threads` threads.
Outcome run(const Scene<float>& s, int threads) {
  harness::set_threads(threads);
  Render<float> r = render(s);
  const auto gi = random_weights(r.image.size(), 3), ga = random_weights(r.alpha.size(), 4);
  Grads<float> g = backward(s, r, std::vector<float>(gi.begin(), gi.end()),
                            std::vector<float>(ga.begin(), ga.end()));
  harness::set_threads(0);
  return {std::move(r), std::move(g)};
}

}  // namespace

TEST_CASE(forward_and_backward_independent_of_threads) {
  // channel counts 1 and 3 (the specialised loops) and 4 (the generic one); many tiles, sizes
  // not tile multiples, Gaussians spanning several tiles and overlapping in each
  for (const int channels : {1, 3, 4}) {
    const Scene<float> s = random_scene(40 + channels, 600, 83, 61, channels, -1).cast<float>();
    const Outcome one = run(s, 1);
    std::printf("  C=%d: %zu visible, %zu tile pairs\n", channels,
                one.render.state.bins.order.size(), one.render.state.bins.ranks.size());
    CHECK(one.render.state.bins.ranks.size() > 2 * one.render.state.bins.order.size(),
          "the scene should put Gaussians on several tiles each");
    for (const int threads : {2, 3, 7}) {
      const Outcome other = run(s, threads);
      const Grads<float>&a = one.grads, &b = other.grads;
      CHECK(one.render.image == other.render.image && one.render.alpha == other.render.alpha,
            "C=", channels, ": forward differs with ", threads, " threads");
      CHECK(a.means == b.means && a.quats == b.quats && a.scales == b.scales &&
                a.opacities == b.opacities && a.colors == b.colors && a.mean2d == b.mean2d &&
                a.mean2d_abs == b.mean2d_abs && a.background == b.background &&
                std::equal(a.viewmat, a.viewmat + 16, b.viewmat),
            "C=", channels, ": gradients differ with ", threads, " threads");
    }
  }
}

TEST_CASE(parallel_binning_independent_of_threads) {
  // enough Gaussians and tile pairs that the binning runs in parallel (kParallelMinItems): its
  // lists are a serial pass's (check_bins) and the same for every thread count
  const Scene<float> s = random_scene(11, 24000, 203, 157, 1, -1).cast<float>();
  const Outcome one = run(s, 1);
  const TileBins& a = one.render.state.bins;
  std::printf("  %zu visible, %zu tile pairs\n", a.order.size(), a.ranks.size());
  CHECK(std::int64_t(a.order.size()) >= spikegs::kParallelMinItems, "too few visible");
  check_bins(one.render.state, s.cam, "one thread");
  for (const int threads : {2, 3, 7}) {
    const Outcome other = run(s, threads);
    const TileBins& b = other.render.state.bins;
    CHECK(a.order == b.order && a.rect == b.rect && a.offsets == b.offsets && a.ranks == b.ranks &&
              a.rank_begin == b.rank_begin,
          "bins differ with ", threads, " threads");
    CHECK(one.render.image == other.render.image && one.grads.means == other.grads.means &&
              one.grads.opacities == other.grads.opacities,
          "forward or backward differs with ", threads, " threads");
  }
}

TEST_CASE(parallel_binning_of_few_gaussians_over_many_tiles) {
  // 0, 1, 6, 9 Gaussians each covering thousands of tiles: fewer ranks than threads, runs of one
  // rank, and no Gaussian at all
  for (const int n : {0, 1, 6, 9}) {
    Scene<float> s = random_scene(5 + n, n, 1024, 768, 1, -1).cast<float>();
    for (float& scale : s.scales) scale *= 400;
    const Outcome one = run(s, 1);
    const TileBins& a = one.render.state.bins;
    std::printf("  n=%d: %zu visible, %zu tile pairs\n", n, a.order.size(), a.ranks.size());
    CHECK(n < 6 || std::int64_t(a.ranks.size()) >= spikegs::kParallelMinItems, "n=", n,
          ": too few pairs to bin in parallel");
    check_bins(one.render.state, s.cam, "few Gaussians");
    for (const int threads : {2, 7, 16}) {
      const Outcome other = run(s, threads);
      const TileBins& b = other.render.state.bins;
      CHECK(a.order == b.order && a.offsets == b.offsets && a.ranks == b.ranks &&
                a.rank_begin == b.rank_begin,
            "n=", n, ": bins differ with ", threads, " threads");
      CHECK(one.render.image == other.render.image && one.grads.means == other.grads.means, "n=", n,
            ": forward or backward differs with ", threads, " threads");
    }
  }
}
