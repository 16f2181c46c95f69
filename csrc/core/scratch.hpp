// A scratch array for one call whose memory the calling thread keeps for its next call.
#pragma once
#include <cstddef>
#include <memory>

namespace spikegs {

// Scratch arrays up to this size are kept by the calling thread for its next call.
constexpr std::size_t kKeptScratchBytes = std::size_t(512) << 20;

// `size` uninitialised elements for one call, for a large array needed once a call (the
// backward's per-pair gradient shares, 53 MB at 200k Gaussians on 256²): allocated afresh, its
// pages were mapped and zeroed by the kernel on every call (13k page faults, a third of the
// backward). Up to kKeptScratchBytes the calling thread keeps the memory for its next call (and
// holds its largest such array until it exits); a larger array is freed after the call, so that
// one huge render does not hold its memory for the life of the process, and so is one made while
// another Scratch<T> of the thread holds the kept array. Its contents do not survive it.
template <typename T>
class Scratch {
 public:
  explicit Scratch(std::size_t size) {
    Kept& kept = kept_array();
    if (size > kKeptScratchBytes / sizeof(T) || kept.in_use) {
      owned_.reset(new T[size]);
      data_ = owned_.get();
      return;
    }
    if (size > kept.capacity) {
      kept.array.reset();  // the old array freed before the new one is allocated
      kept.capacity = 0;   // and forgotten, should the allocation throw
      kept.array.reset(new T[size]);
      kept.capacity = size;
    }
    kept.in_use = true;
    data_ = kept.array.get();
  }
  ~Scratch() {
    if (!owned_) kept_array().in_use = false;
  }
  Scratch(const Scratch&) = delete;
  Scratch& operator=(const Scratch&) = delete;
  T* get() const { return data_; }

 private:
  struct Kept {
    std::unique_ptr<T[]> array;
    std::size_t capacity = 0;
    bool in_use = false;  // a Scratch<T> of this thread holds it
  };
  static Kept& kept_array() {
    static thread_local Kept kept;
    return kept;
  }
  std::unique_ptr<T[]> owned_;
  T* data_ = nullptr;
};

}  // namespace spikegs
