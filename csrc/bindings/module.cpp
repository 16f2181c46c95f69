// The pybind11 module spikegs._C: numpy arrays in and out, the GIL released around the core.
#include <stdexcept>
#include <string>

#include "bindings/register.hpp"
#include "core/thread_buffers.hpp"

PYBIND11_MODULE(_C, m) {
  m.doc() = "SpikeGS C++ core: Gaussian rasterizer and spike-stream kernels";
  spikegs::require_cpu_features(m);  // before any of the core's code runs
  spikegs::bind_rasterizer(m);
  spikegs::bind_spikes(m);
  // the OpenMP runtime the core was linked with, which torch.set_num_threads does not reach where
  // torch brings another one
  m.def(
      "set_max_threads",
      [](int n) {
        if (n < 1) throw std::invalid_argument("n expected >= 1, found " + std::to_string(n));
        spikegs::set_max_threads(n);
      },
      pybind11::arg("n"),
      "Team size of the calling thread's next parallel regions in the core (n >= 1)");
  m.def("max_threads", &spikegs::max_threads,
        "Team size of the calling thread's next parallel regions in the core (1 without OpenMP)");
  // the build a run's record names (CMakeLists.txt): its source, compiler, options and threads
  pybind11::dict build;
  build["source"] = SPIKEGS_SOURCE;
  build["compiler"] = SPIKEGS_COMPILER;
  build["options"] = SPIKEGS_OPTIONS;
#ifdef _OPENMP
  build["openmp"] = true;
#else
  build["openmp"] = false;
#endif
  m.attr("build") = build;
}
