// Each part of the core binds itself into spikegs._C from its own file.
#pragma once
#include <pybind11/pybind11.h>

namespace spikegs {
void bind_rasterizer(pybind11::module_& m);  // bindings/rasterizer.cpp
void bind_spikes(pybind11::module_& m);      // bindings/spikes.cpp
// throws ImportError on a CPU without an extension the core was compiled for
void require_cpu_features(pybind11::module_& m);  // bindings/cpu_check.cpp
}  // namespace spikegs
