// Spike-stream part of spikegs._C: layouts, decode/encode, window counts, TFP, TFI, simulator.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>

#include "bindings/register.hpp"
#include "core/spike_format.hpp"
#include "core/spike_kernels.hpp"
#include "core/spike_simulator.hpp"

namespace py = pybind11;

namespace spikegs {
namespace {

using Bytes = py::array_t<uint8_t, py::array::c_style>;
using Indices = py::array_t<int64_t, py::array::c_style | py::array::forcecast>;

std::string shape_of(const py::array& a) {
  std::ostringstream os;
  os << "[";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) os << (d ? ", " : "") << a.shape(d);
  os << "]";
  return os.str();
}

// The packed stream in `data` (all of its bytes, any shape) under `layout`.
PackedStream stream_of(const Bytes& data, const SpikeLayout& layout) {
  return PackedStream::over(data.data(), int64_t(data.size()), layout);
}

// window_counts' checks, as per_index's `check`
auto windows_checked(int64_t w) {
  return [w](const PackedStream& s, const int64_t* k, int64_t B) { check_windows(s, k, B, w); };
}

// out [B, H, W] of T from kernel(stream, idx, B, out), run without the GIL, after check(stream,
// idx, B) (the kernel's own checks, before the output is allocated). `indices`: integers only (an
// array or a list): a cast truncated floats (0.7 read readout 0) and read booleans.
template <typename T, typename Check, typename Kernel>
py::array_t<T> per_index(const Bytes& data, const SpikeLayout& layout, const py::object& given,
                         const char* what, Check&& check, Kernel&& kernel) {
  const PackedStream s = stream_of(data, layout);
  const py::array indices = py::array::ensure(given);
  if (!indices) throw py::type_error(std::string(what) + " expected an array of integers");
  const char kind = indices.dtype().kind();
  if (kind != 'i' && kind != 'u')
    throw py::type_error(std::string(what) + " expected integers, found dtype " +
                         std::string(py::str(indices.dtype())));
  if (kind == 'u' && indices.itemsize() == 8) {  // past int64: the cast below wrapped them
    using Unsigned = py::array_t<uint64_t, py::array::c_style | py::array::forcecast>;
    const Unsigned u(indices);  // (raises the conversion's error, a copy's MemoryError)
    for (py::ssize_t i = 0; i < u.size(); ++i)
      if (u.data()[i] > uint64_t(std::numeric_limits<int64_t>::max()))
        throw std::invalid_argument(std::string(what) + " expected below 2^63, found " +
                                    std::to_string(u.data()[i]));
  }
  const Indices idx(indices);
  if (idx.ndim() != 1)
    throw std::invalid_argument(std::string(what) + " expected 1-D, found shape " + shape_of(idx));
  const int64_t B = idx.shape(0);
  check(s, idx.data(), B);  // before allocating: a batch of bad indices is told so, not MemoryError
  py::array_t<T> out({B, layout.height, layout.width});
  const int64_t* k = idx.data();
  T* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    kernel(s, k, B, o);
  }
  return out;
}

py::array_t<uint8_t> unpack(const Bytes& data, const SpikeLayout& layout, int64_t t0, int64_t n) {
  const PackedStream s = stream_of(data, layout);
  check_range(s, t0, n);  // before allocating: a bad n is named, not a numpy MemoryError
  py::array_t<uint8_t> out({std::max<int64_t>(n, 0), layout.height, layout.width});
  uint8_t* o = out.mutable_data();
  py::gil_scoped_release release;
  unpack_frames(s, t0, n, o);
  return out;
}

py::array_t<uint8_t> pack(
    const py::array_t<uint8_t, py::array::c_style | py::array::forcecast>& bits,
    const SpikeLayout& layout) {
  layout.validate();
  if (bits.ndim() != 3 || bits.shape(1) != layout.height || bits.shape(2) != layout.width)
    throw std::invalid_argument("bits expected [T, " + std::to_string(layout.height) + ", " +
                                std::to_string(layout.width) + "], found " + shape_of(bits));
  const int64_t n = bits.shape(0);
  py::array_t<uint8_t> out({n, layout.frame_bytes()});
  const uint8_t* b = bits.data();
  uint8_t* o = out.mutable_data();
  py::gil_scoped_release release;
  pack_frames(b, n, layout, o);
  return out;
}

py::array_t<uint8_t> repack(const Bytes& data, const SpikeLayout& layout, int64_t t0, int64_t n,
                            const SpikeLayout& dst) {
  const PackedStream s = stream_of(data, layout);
  dst.validate();
  check_range(s, t0, n);  // before allocating, as unpack
  py::array_t<uint8_t> out({std::max<int64_t>(n, 0), dst.frame_bytes()});
  uint8_t* o = out.mutable_data();
  py::gil_scoped_release release;
  repack_frames(s, t0, n, dst, o);
  return out;
}

py::array_t<uint8_t> run_simulator(
    SpikeSimulator& sim,
    const py::array_t<float, py::array::c_style | py::array::forcecast>& frames,
    const py::array_t<double, py::array::c_style | py::array::forcecast>& times, int64_t n) {
  const int64_t H = sim.height(), W = sim.width();
  if (frames.ndim() != 3 || frames.shape(1) != H || frames.shape(2) != W)
    throw std::invalid_argument("frames expected [F, " + std::to_string(H) + ", " +
                                std::to_string(W) + "], found " + shape_of(frames));
  if (times.ndim() != 1 || times.shape(0) != frames.shape(0))
    throw std::invalid_argument("times expected [" + std::to_string(frames.shape(0)) + "], found " +
                                shape_of(times));
  if (n < 0) throw std::invalid_argument("readouts expected >= 0, found " + std::to_string(n));
  py::array_t<uint8_t> out({n, H, (W + 7) / 8});
  const float* f = frames.data();
  const double* t = times.data();
  uint8_t* o = out.mutable_data();
  py::gil_scoped_release release;
  // one run at a time: a simulator's voltages and readout counter are its state (Python threads
  // running one simulator at once corrupted both), and a run uses every core already
  static std::mutex running;
  const std::lock_guard<std::mutex> lock(running);
  sim.run(f, t, frames.shape(0), n, o);
  return out;
}

}  // namespace

void bind_spikes(py::module_& m) {
  py::class_<SpikeLayout>(m, "SpikeLayout",
                          "Where each pixel's bit lives in a packed frame (see spike_format.hpp).")
      .def_static("memory", &SpikeLayout::memory, py::arg("height"), py::arg("width"),
                  "[T, H, ceil(W/8)] rows padded to bytes, unflipped")
      .def_static("dat", &SpikeLayout::dat, py::arg("height"), py::arg("width"), py::arg("flip"),
                  py::arg("raw_width") = 0, py::arg("col_offset") = 0, "the .dat file layout")
      .def_readonly("height", &SpikeLayout::height)
      .def_readonly("width", &SpikeLayout::width)
      .def_readonly("row_bits", &SpikeLayout::row_bits)
      .def_readonly("col_offset", &SpikeLayout::col_offset)
      .def_readonly("flip", &SpikeLayout::flip)
      .def_property_readonly("frame_bytes", &SpikeLayout::frame_bytes);

  m.attr("TFI_DEFAULT_MAX_INTERVAL") = kTfiDefaultMaxInterval;
  m.attr("TFI_MAX_INTERVAL") = kTfiMaxInterval;
  m.attr("MAX_WINDOW") = kMaxWindow;
  m.def("spike_unpack", &unpack, py::arg("data"), py::arg("layout"), py::arg("t0"), py::arg("n"),
        "readouts [t0, t0+n) as 0/1 uint8 [n, H, W]");
  m.def("spike_pack", &pack, py::arg("bits"), py::arg("layout"),
        "bits [n, H, W] packed into [n, layout.frame_bytes]");
  m.def("spike_repack", &repack, py::arg("data"), py::arg("layout"), py::arg("t0"), py::arg("n"),
        py::arg("dst"), "readouts [t0, t0+n) re-encoded in layout dst: [n, dst.frame_bytes]");
  m.def(
      "spike_counts",
      [](const Bytes& data, const SpikeLayout& layout, const py::object& starts, int64_t w) {
        return per_index<int32_t>(data, layout, starts, "starts", windows_checked(w),
                                  [w](const PackedStream& s, const int64_t* k, int64_t B,
                                      int32_t* o) { window_counts<int32_t>(s, k, B, w, o); });
      },
      py::arg("data"), py::arg("layout"), py::arg("starts"), py::arg("w"),
      "spikes in readouts [start, start+w): int32 [B, H, W]");
  m.def(
      "spike_tfp",
      [](const Bytes& data, const SpikeLayout& layout, const py::object& starts, int64_t w) {
        return per_index<float>(data, layout, starts, "starts", windows_checked(w),
                                [w](const PackedStream& s, const int64_t* k, int64_t B, float* o) {
                                  window_counts<float>(s, k, B, w, o);
                                });
      },
      py::arg("data"), py::arg("layout"), py::arg("starts"), py::arg("w"),
      "mean spike rate over readouts [start, start+w): float32 [B, H, W]");
  m.def(
      "spike_tfi",
      [](const Bytes& data, const SpikeLayout& layout, const py::object& ks, int64_t max_interval) {
        return per_index<float>(
            data, layout, ks, "readouts",
            [max_interval](const PackedStream& s, const int64_t* k, int64_t B) {
              check_tfi(s, k, B, max_interval);
            },
            [max_interval](const PackedStream& s, const int64_t* k, int64_t B, float* o) {
              tfi(s, k, B, max_interval, o);
            });
      },
      py::arg("data"), py::arg("layout"), py::arg("ks"),
      py::arg("max_interval") = kTfiDefaultMaxInterval,
      "1 / min(interval between the spikes around k, max_interval): float32 [B, H, W]");

  py::class_<SimParams>(m, "SimParams", "Simulator parameters (see spike_simulator.hpp)")
      .def(py::init<>())
      .def_readwrite("threshold", &SimParams::threshold)
      .def_readwrite("rate_at_one", &SimParams::rate_at_one)
      .def_readwrite("dark_rate", &SimParams::dark_rate)
      .def_readwrite("dark_sigma", &SimParams::dark_sigma)
      .def_readwrite("fpn_sigma", &SimParams::fpn_sigma)
      .def_readwrite("temporal_sigma", &SimParams::temporal_sigma)
      .def_readwrite("shot_noise", &SimParams::shot_noise)
      .def_readwrite("random_init", &SimParams::random_init)
      .def_property_readonly("saturated_light", &SimParams::saturated_light,
                             "the most light the simulator takes (fires every readout)");
  py::class_<SpikeSimulator>(m, "SpikeSimulator", "Integrate-and-fire spike camera simulator")
      .def(py::init<int64_t, int64_t, const SimParams&, uint64_t>(), py::arg("height"),
           py::arg("width"), py::arg("params"), py::arg("seed"))
      .def("run", &run_simulator, py::arg("frames"), py::arg("times"), py::arg("n"),
           "the next n readouts under frames [F, H, W] at readout times [F]: [n, H, ceil(W/8)]");
}

}  // namespace spikegs
