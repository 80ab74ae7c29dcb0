// CPU time next to wall time, for benchmarks on a shared machine. With other processes on the
// cores, a thread's wall time grows with the share of the core it did not get; the process's
// CPU time (all its threads) counts only what it ran, so rays per CPU-second compare two
// measurements taken under different load (as long as both run the same number of threads,
// busy throughout). Wall-clock figures are reported next to them.
#pragma once

#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace prt::bench {

using Clock = std::chrono::steady_clock;

/// Milliseconds of the steady clock since t0.
inline double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// The median of v (the mean of the middle two for an even count; 0 when empty).
inline double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// CPU seconds used so far by every thread of this process.
inline double processCpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

/// Samples (wall, process CPU) every 2 ms on a thread of its own, so that the CPU time of an
/// interval known only by its wall-clock ends (a stage inside a bake) can be read afterwards.
class CpuTimeline {
 public:
  CpuTimeline() : thread_([this] { run(); }) {}
  ~CpuTimeline() {
    stop_ = true;
    thread_.join();
  }
  CpuTimeline(const CpuTimeline&) = delete;
  CpuTimeline& operator=(const CpuTimeline&) = delete;

  /// Process CPU seconds between two wall-clock instants (linear between samples; within 2 ms).
  double cpuSeconds(Clock::time_point a, Clock::time_point b) {
    sample();
    return cpuAt(b) - cpuAt(a);
  }

 private:
  void sample() {
    const auto now = Clock::now();
    const double cpu = processCpuSeconds();
    std::lock_guard<std::mutex> lock(mutex_);
    samples_.emplace_back(now, cpu);
  }
  void run() {
    while (!stop_) {
      sample();
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }
  double cpuAt(Clock::time_point t) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = std::lower_bound(
        samples_.begin(), samples_.end(), t,
        [](const std::pair<Clock::time_point, double>& s, Clock::time_point x) { return s.first < x; });
    if (it == samples_.begin()) return it->second;
    if (it == samples_.end()) return samples_.back().second;
    const auto& [t1, c1] = *it;
    const auto& [t0, c0] = *(it - 1);
    const double span = std::chrono::duration<double>(t1 - t0).count();
    const double f = span > 0 ? std::chrono::duration<double>(t - t0).count() / span : 1.0;
    return c0 + f * (c1 - c0);
  }

  std::mutex mutex_;
  std::vector<std::pair<Clock::time_point, double>> samples_;
  std::atomic<bool> stop_{false};
  std::thread thread_;  // last: starts once the members above exist
};

}  // namespace prt::bench
