#include "bindings/register.hpp"

namespace spikegs {
void bind_spikes(pybind11::module_&) {}
}  // namespace spikegs
