// Each part of the core binds itself into spikegs._C from its own file.
#pragma once
#include <pybind11/pybind11.h>

namespace spikegs {
void bind_rasterizer(pybind11::module_& m);  // bindings/rasterizer.cpp
void bind_spikes(pybind11::module_& m);      // bindings/spikes.cpp
}  // namespace spikegs
