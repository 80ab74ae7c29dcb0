// Time spent inside Embree's calls, summed over every thread of a bake: what of the bake is
// tracing, measured in the bake itself (ProbeStats::traceSeconds, StageStats::traceSeconds;
// the benches' share not tracing). Two clock reads a call, a call being a stream of rays.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>

namespace prt::bake {

class TraceClock {
public:
  template <class F>
  void time(F&& call) {
    const auto t0 = std::chrono::steady_clock::now();
    call();
    nanos_.fetch_add(std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count(),
                     std::memory_order_relaxed);
  }
  double seconds() const { return 1e-9 * double(nanos_.load(std::memory_order_relaxed)); }

private:
  std::atomic<int64_t> nanos_{0};
};

}  // namespace prt::bake
