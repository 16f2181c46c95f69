// The pybind11 module spikegs._C: numpy arrays in and out, the GIL released around the core.
#include "bindings/register.hpp"

PYBIND11_MODULE(_C, m) {
  m.doc() = "SpikeGS C++ core: Gaussian rasterizer and spike-stream kernels";
  spikegs::require_cpu_features(m);  // before any of the core's code runs
  spikegs::bind_rasterizer(m);
  spikegs::bind_spikes(m);
}
