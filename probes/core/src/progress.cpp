#include "prt/progress.h"

#include <sys/resource.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace prt {

Progress::Progress(std::string label, uint64_t total, std::string unit, bool enabled)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(total),
      enabled_(enabled),
      start_(std::chrono::steady_clock::now()) {}

Progress::~Progress() {
  if (!finished_) finish();
}

bool Progress::terminalDefault() { return ::isatty(STDERR_FILENO) && std::getenv("PRT_NO_PROGRESS") == nullptr; }

double Progress::elapsedSeconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::add(uint64_t n) {
  done_.fetch_add(n, std::memory_order_relaxed);
  if (!enabled_) return;
  int64_t now = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - start_).count();
  int64_t last = lastDrawNs_.load(std::memory_order_relaxed);
  // Redraw at most 10 times a second, by whichever thread gets there first.
  if (now - last < 100'000'000) return;
  if (!lastDrawNs_.compare_exchange_strong(last, now)) return;
  std::unique_lock lock(drawMutex_, std::try_to_lock);
  if (lock.owns_lock()) draw(false);
}

void Progress::finish() {
  if (finished_) return;
  finished_ = true;
  if (!enabled_) return;
  std::lock_guard lock(drawMutex_);
  draw(true);
  std::fputc('\n', stderr);
}

void Progress::draw(bool final) {
  uint64_t done = std::min(done_.load(), total_);
  double t = elapsedSeconds();
  double frac = total_ ? double(done) / double(total_) : 1.0;
  constexpr int kWidth = 30;
  int filled = int(frac * kWidth);
  std::string bar(size_t(filled), '#');
  bar.resize(kWidth, '.');
  double rate = t > 0 ? double(done) / t : 0.0;
  std::string eta = "--";
  if (final) {
    eta = "done";
  } else if (rate > 0 && done > 0) {
    double left = double(total_ - done) / rate;
    char buf[32];
    std::snprintf(buf, sizeof buf, "%dm%02ds", int(left) / 60, int(left) % 60);
    eta = buf;
  }
  std::fprintf(stderr, "\r%-12s [%s] %5.1f%%  %s %s/s  %s %s   ", label_.c_str(), bar.c_str(), 100.0 * frac,
               formatCount(rate).c_str(), unit_.c_str(), final ? "in" : "ETA",
               final ? (std::to_string(int(t)) + "s").c_str() : eta.c_str());
  std::fflush(stderr);
}

uint64_t peakMemoryBytes() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return uint64_t(ru.ru_maxrss) * 1024u;
}

std::string formatBytes(uint64_t bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = double(bytes);
  int u = 0;
  while (v >= 1024.0 && u < 4) {
    v /= 1024.0;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", v, units[u]);
  return buf;
}

std::string formatCount(double n) {
  const char* units[] = {"", " k", " M", " G", " T"};
  int u = 0;
  while (std::fabs(n) >= 1000.0 && u < 4) {
    n /= 1000.0;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f%s" : "%.2f%s", n, units[u]);
  return buf;
}

}  // namespace prt
