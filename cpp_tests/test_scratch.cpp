// Scratch: kept by the thread up to kKeptScratchBytes (the same memory from call to call, grown
// when a call needs more), a larger array, or one made while the kept one is held, owned by its
// call only.
#include "core/scratch.hpp"
#include "harness.hpp"

using spikegs::kKeptScratchBytes;
using spikegs::Scratch;

TEST_CASE(scratch_kept_up_to_the_cap_and_freed_above) {
  const std::size_t cap = kKeptScratchBytes / sizeof(double);
  const double* first;
  {
    const Scratch<double> a(1000);
    first = a.get();
  }
  {
    const Scratch<double> b(500);  // smaller: the kept array again
    CHECK(b.get() == first, "a smaller array did not reuse the kept one");
  }
  const double* grown;
  {
    const Scratch<double> c(cap);  // at the cap: still kept
    grown = c.get();
    c.get()[cap - 1] = 1.0;  // writable to its last element
  }
  {
    const Scratch<double> d(10);
    CHECK(d.get() == grown, "the array grown to the cap was not kept");
  }
  {
    const Scratch<double> e(cap + 1);  // above the cap: its own, not the kept one
    CHECK(e.get() != grown, "an array above the cap used the kept one");
    e.get()[cap] = 1.0;
  }
  {
    const Scratch<double> f(10);
    CHECK(f.get() == grown, "an array above the cap replaced the kept one");
  }
  {
    const Scratch<double> outer(10);  // the kept array
    const Scratch<double> inner(10);  // made while it is held: its own
    CHECK(outer.get() == grown && inner.get() != grown, "a nested Scratch shared the kept array");
  }
  {
    const Scratch<double> h(10);  // released by the outer one: kept again
    CHECK(h.get() == grown, "the kept array was not released");
  }
  {
    const Scratch<float> g(10);  // one kept array per element type
    CHECK(static_cast<const void*>(g.get()) != static_cast<const void*>(grown),
          "float and double share a kept array");
  }
}
