// Progress on a terminal: a bar with rate and ETA on stderr when it is a TTY, silent otherwise
// (logs, CI, --quiet). Thread-safe: workers call add() from any thread.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace prt {

class Progress {
 public:
  /// `unit` names what is counted ("vertices", "rays"). enabled=false keeps it silent.
  Progress(std::string label, uint64_t total, std::string unit, bool enabled);
  ~Progress();
  void add(uint64_t n);
  /// Prints the final state of the bar (if shown) and a newline.
  void finish();
  double elapsedSeconds() const;
  /// True when stderr is a terminal and PRT_NO_PROGRESS is unset.
  static bool terminalDefault();

 private:
  void draw(bool final);
  std::string label_, unit_;
  uint64_t total_;
  bool enabled_;
  bool finished_ = false;
  std::atomic<uint64_t> done_{0};
  std::chrono::steady_clock::time_point start_;
  std::atomic<int64_t> lastDrawNs_{0};
  std::mutex drawMutex_;
};

/// Peak resident memory of this process so far, in bytes (getrusage).
uint64_t peakMemoryBytes();
/// "1.2 GiB", "340 MiB", ...
std::string formatBytes(uint64_t bytes);
/// "1.23 M", "45.6 k", ...
std::string formatCount(double n);

}  // namespace prt
