// Per-thread scratch buffers allocated before a parallel region. An exception that leaves an
// OpenMP region terminates the process, so a buffer allocated inside one (a tile's colour
// accumulators grow with the channel count) turned an out-of-memory into an abort; allocated
// here, it reaches the caller as std::bad_alloc (Python: MemoryError).
#pragma once
#include <cstddef>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace spikegs {

// The most threads a parallel region opened here can have, and the calling thread's number in it.
inline int max_threads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

// Sets the calling thread's team size for the parallel regions it opens next (n >= 1).
inline void set_max_threads(int n) {
#ifdef _OPENMP
  omp_set_num_threads(n);
#else
  (void)n;
#endif
}

inline int thread_number() {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

// Loops over fewer items than this run on the calling thread alone: under OMP_WAIT_POLICY=PASSIVE
// (spikegs sets it) waking the team costs tens of microseconds, more than such a loop's work
// (binning 1000 Gaussians took 0.15 ms longer in parallel).
constexpr long kParallelMinItems = 1 << 14;

// `size` zero-initialised elements for each thread of the next parallel region: [threads, size].
template <typename T>
class ThreadBuffers {
 public:
  explicit ThreadBuffers(std::size_t size)
      : size_(size), data_(size * std::size_t(max_threads()), T(0)) {}

  // The calling thread's buffer, [size]; called inside the region.
  T* local() { return data_.data() + size_ * std::size_t(thread_number()); }

 private:
  std::size_t size_;
  std::vector<T> data_;
};

}  // namespace spikegs
