// The x86 instruction-set extensions that the core was compiled to use. With SPIKEGS_NATIVE
// (-march=native, the default) they are those of the machine that built it, and the core run on
// a CPU without one of them stops at its first such instruction ("Illegal instruction"): a build
// shared across machines (a cluster's login node and its older compute nodes) does that. The
// bindings, compiled without -march=native, compare this list with the running CPU at import.
#pragma once

namespace spikegs {

// Space-separated names as GCC's and Clang's __builtin_cpu_supports spell them ("avx2
// avx512f ..."); empty on other architectures and for a build without extensions beyond SSE2.
// Only the core's own flags decide it: it is defined in the core's translation unit, and it is
// data, no vector code, so that calling it is safe on any CPU.
const char* compiled_cpu_features();

}  // namespace spikegs
