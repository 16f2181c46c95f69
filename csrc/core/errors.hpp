// Bad input from the core: std::invalid_argument built from streamed parts (Python sees
// ValueError).
#pragma once
#include <sstream>
#include <stdexcept>

namespace spikegs {
template <typename... Args>
[[noreturn]] void fail(const Args&... args) {
  std::ostringstream os;
  (os << ... << args);
  throw std::invalid_argument(os.str());
}
}  // namespace spikegs
