// spikegs._C refuses to load on a CPU without an extension that its core was compiled for
// (core/cpu_features.hpp), instead of stopping the process at "Illegal instruction".
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "bindings/register.hpp"
#include "core/cpu_features.hpp"

namespace py = pybind11;

namespace spikegs {
namespace {

// This CPU's extensions among those that compiled_cpu_features can name: {name: present}.
std::map<std::string, bool> cpu_features() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  return {
      {"sse3", __builtin_cpu_supports("sse3")},
      {"ssse3", __builtin_cpu_supports("ssse3")},
      {"sse4.1", __builtin_cpu_supports("sse4.1")},
      {"sse4.2", __builtin_cpu_supports("sse4.2")},
      {"popcnt", __builtin_cpu_supports("popcnt")},
      {"avx", __builtin_cpu_supports("avx")},
      {"avx2", __builtin_cpu_supports("avx2")},
      {"fma", __builtin_cpu_supports("fma")},
      {"bmi", __builtin_cpu_supports("bmi")},
      {"bmi2", __builtin_cpu_supports("bmi2")},
      {"avx512f", __builtin_cpu_supports("avx512f")},
      {"avx512vl", __builtin_cpu_supports("avx512vl")},
      {"avx512bw", __builtin_cpu_supports("avx512bw")},
      {"avx512dq", __builtin_cpu_supports("avx512dq")},
      {"avx512cd", __builtin_cpu_supports("avx512cd")},
      {"avx512vbmi", __builtin_cpu_supports("avx512vbmi")},
      {"avx512ifma", __builtin_cpu_supports("avx512ifma")},
      {"avx512vpopcntdq", __builtin_cpu_supports("avx512vpopcntdq")},
      {"avx512vnni", __builtin_cpu_supports("avx512vnni")},
      {"avx512vbmi2", __builtin_cpu_supports("avx512vbmi2")},
      {"avx512bitalg", __builtin_cpu_supports("avx512bitalg")},
  };
#else
  return {};
#endif
}

std::vector<std::string> words(const std::string& text) {
  std::istringstream in(text);
  std::vector<std::string> out;
  for (std::string w; in >> w;) out.push_back(w);
  return out;
}

// Why a core compiled with the extensions `compiled` (space-separated) cannot run on a CPU with
// `cpu` ({name: present}; a name it lacks counts as absent); "" where it can.
std::string cpu_mismatch(const std::string& compiled, const std::map<std::string, bool>& cpu) {
  std::string missing;
  for (const std::string& name : words(compiled)) {
    const auto it = cpu.find(name);
    if (it == cpu.end() || !it->second) missing += (missing.empty() ? "" : ", ") + name;
  }
  if (missing.empty()) return "";
  return "spikegs._C was compiled for a CPU with " + missing +
         ", which this CPU lacks: its core would stop the process at the first such instruction "
         "(\"Illegal instruction\"). A build is tuned to the machine that compiles it "
         "(-march=native, CMake option SPIKEGS_NATIVE, on by default): reinstall SpikeGS on "
         "this machine (pip install --force-reinstall --no-deps .), or build one that runs on "
         "any x86-64 CPU (pip install . -C cmake.define.SPIKEGS_NATIVE=OFF)";
}

}  // namespace

void require_cpu_features(py::module_& m) {
  const std::map<std::string, bool> cpu = cpu_features();
  const std::string mismatch = cpu_mismatch(compiled_cpu_features(), cpu);
  if (!mismatch.empty()) throw py::import_error(mismatch);
  m.attr("compiled_cpu_features") = words(compiled_cpu_features());
  m.attr("cpu_features") = cpu;
  m.def("cpu_mismatch", &cpu_mismatch, py::arg("compiled"), py::arg("cpu"),
        "Why a core compiled with the extensions `compiled` (space-separated) cannot run on a "
        "CPU with `cpu` ({name: present}); '' where it can");
}

}  // namespace spikegs
