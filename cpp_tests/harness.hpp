// A minimal test harness: TEST_CASE(name) { ... } registers a case; CHECK(cond, msg...) records a
// failure. `exe NAME` runs one case (ctest does this, one test per case), `exe` runs them all.
#pragma once
#ifdef _OPENMP
#include <omp.h>
#endif

#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <map>
#include <sstream>
#include <string>

namespace harness {
inline std::map<std::string, std::function<void()>>& registry() {
  static std::map<std::string, std::function<void()>> cases;
  return cases;
}
inline int& failures() {
  static int count = 0;
  return count;
}
struct Register {
  Register(const char* name, std::function<void()> fn) { registry()[name] = std::move(fn); }
};
template <typename... Args>
void fail(const char* file, int line, const char* cond, Args&&... args) {
  std::ostringstream os;
  (os << ... << args);
  std::fprintf(stderr, "%s:%d: CHECK(%s) failed %s\n", file, line, cond, os.str().c_str());
  ++failures();
}
// OpenMP's thread count from here on, 0 for one a core; a build without OpenMP has one thread.
inline void set_threads(int threads) {
#ifdef _OPENMP
  omp_set_num_threads(threads > 0 ? threads : omp_get_num_procs());
#else
  (void)threads;
#endif
}
}  // namespace harness

#define TEST_CASE(name)                                  \
  static void name();                                    \
  static harness::Register register_##name(#name, name); \
  static void name()

#define CHECK(cond, ...)                                                      \
  do {                                                                        \
    if (!(cond)) harness::fail(__FILE__, __LINE__, #cond, "", ##__VA_ARGS__); \
  } while (0)

int main(int argc, char** argv) {
  auto& cases = harness::registry();
  int ran = 0;
  for (auto& [name, fn] : cases) {
    if (argc > 1 && std::strcmp(argv[1], name.c_str()) != 0) continue;
    std::printf("[ RUN  ] %s\n", name.c_str());
    int before = harness::failures();
    fn();
    std::printf("[ %s ] %s\n", harness::failures() == before ? " OK " : "FAIL", name.c_str());
    ++ran;
  }
  if (ran == 0) {
    std::fprintf(stderr, "no test case named %s\n", argc > 1 ? argv[1] : "(any)");
    return 2;
  }
  return harness::failures() == 0 ? 0 : 1;
}
