// Time spent inside Embree's calls, summed over every thread of a bake: what of the bake is
// tracing, measured in the bake itself (ProbeStats::traceSeconds, StageStats::traceSeconds;
// the benches' share not tracing). Two clock reads a call, a call being a stream of rays.
#pragma once

#include <tbb/task_arena.h>

#include <array>
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
    const auto nanos = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0);
    slot().fetch_add(nanos.count(), std::memory_order_relaxed);
  }
  double seconds() const {
    int64_t sum = 0;
    for (const Slot& s : slots_) sum += s.nanos.load(std::memory_order_relaxed);
    return 1e-9 * double(sum);
  }

 private:
  // One counter a thread, each on its own cache line: a counter shared by every thread moved
  // its line between the cores at every call (a locked add waiting on the other core). Threads
  // outside a TBB arena, or beyond kSlots, share slots; the adds stay atomic, so the sum is right.
  static constexpr int kSlots = 64;
  struct alignas(64) Slot {
    std::atomic<int64_t> nanos{0};
  };
  std::atomic<int64_t>& slot() {
    const int i = tbb::this_task_arena::current_thread_index();
    return slots_[size_t(i < 0 ? 0 : i % kSlots)].nanos;
  }
  std::array<Slot, kSlots> slots_{};
};

}  // namespace prt::bake
