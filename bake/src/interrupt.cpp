#include "prt/bake/interrupt.h"

#include <atomic>

namespace prt::bake {

namespace {

std::atomic<bool> gInterrupt{false};
std::atomic<int> gSignal{0};
static_assert(std::atomic<bool>::is_always_lock_free && std::atomic<int>::is_always_lock_free,
              "the interrupt flag is set from a signal handler");

}  // namespace

void requestInterrupt(int signal) noexcept {
  gSignal.store(signal, std::memory_order_relaxed);
  gInterrupt.store(true, std::memory_order_release);
}
bool interruptRequested() noexcept { return gInterrupt.load(std::memory_order_acquire); }
int interruptSignal() noexcept { return gSignal.load(std::memory_order_relaxed); }
void clearInterrupt() noexcept {
  gInterrupt.store(false);
  gSignal.store(0);
}

}  // namespace prt::bake
