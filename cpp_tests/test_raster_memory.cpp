// The rasterizer never allocates per pixel per Gaussian: the heap its forward and backward use
// grows with the pixels, the Gaussians and the (tile, Gaussian) pairs it bins, not with their
// product, which is up to 256 pixels a pair. Every allocation of this program goes through the
// counting operator new below.
#include <atomic>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <new>

#include "harness.hpp"
#include "raster_scene.hpp"

namespace {

std::atomic<std::size_t> live{0}, peak{0};  // bytes allocated now, and the most since reset
constexpr std::size_t kHeader = alignof(std::max_align_t);  // a block's size, stored before it

void* counted(std::size_t size) {
  void* block = std::malloc(size + kHeader);
  if (!block) throw std::bad_alloc();
  *static_cast<std::size_t*>(block) = size;
  const std::size_t now = live += size;
  for (std::size_t was = peak; now > was && !peak.compare_exchange_weak(was, now);) {
  }
  return static_cast<char*>(block) + kHeader;
}

void uncounted(void* p) noexcept {
  if (!p) return;
  void* block = static_cast<char*>(p) - kHeader;
  live -= *static_cast<std::size_t*>(block);
  std::free(block);
}

}  // namespace

void* operator new(std::size_t size) { return counted(size); }
void* operator new[](std::size_t size) { return counted(size); }
void operator delete(void* p) noexcept { uncounted(p); }
void operator delete[](void* p) noexcept { uncounted(p); }
void operator delete(void* p, std::size_t) noexcept { uncounted(p); }
void operator delete[](void* p, std::size_t) noexcept { uncounted(p); }

using namespace test;

TEST_CASE(heap_grows_with_pairs_not_pixels_times_gaussians) {
  // 1000 Gaussians 30-120 px wide over a 256² image, in float (training's precision), one channel
  Scene<double> wide = random_scene(5, 1000, 256, 256, 1, -1);
  for (double& scale : wide.scales) scale *= 30;
  const Scene<float> s = wide.cast<float>();
  const std::size_t before = live;
  peak = before;
  const Render<float> r = render(s);
  const auto gi = random_weights(r.image.size(), 1), ga = random_weights(r.alpha.size(), 2);
  backward(s, r, std::vector<float>(gi.begin(), gi.end()),
           std::vector<float>(ga.begin(), ga.end()));
  const std::size_t used = peak - before, pairs = r.state.bins.ranks.size();
  const std::size_t pixels = std::size_t(s.cam.width) * s.cam.height, n = std::size_t(s.n);
  // the backward's gradient share, 4 (8 + C) bytes, and the binning's rank, 4, a pair; the state,
  // images and gradients a pixel and a Gaussian; the per-thread buffers
  const std::size_t bound = 64 * pairs + 64 * pixels + 1024 * n + (1 << 20);
  std::printf("  %zu pairs, %zu pixels x %zu Gaussians: %.1f MB used, bound %.1f MB\n", pairs,
              pixels, n, used / 1e6, bound / 1e6);
  CHECK(pixels * n > 2 * bound, "the scene should hold many more pixel pairs than the bound");
  CHECK(used <= bound, used, " bytes used, more than ", bound);
}
