// prt/huge_pages.h: memory that is freed is reused without faulting it in again.
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <cstdlib>
#include <cstring>
#include <memory>

#include "prt/huge_pages.h"

namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitizerAllocator = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kSanitizerAllocator = true;
#else
constexpr bool kSanitizerAllocator = false;
#endif
#else
constexpr bool kSanitizerAllocator = false;
#endif

long minorFaults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt;
}

// Allocates `bytes`, writes every page, frees; the minor faults it took.
long touchFresh(size_t bytes) {
  const long before = minorFaults();
  std::unique_ptr<char[]> p(new char[bytes]);
  std::memset(p.get(), 1, bytes);
  asm volatile("" : : "r"(p.get()) : "memory");  // the writes happen
  p.reset();
  return minorFaults() - before;
}

// A 16 MiB block is above glibc's default threshold for a block mapped on its own (128 KiB, and
// it only grows as such blocks are freed): without keepFreedMemory it is unmapped when freed and
// every one of its 4096 pages faults again the next time. This runs first in its process (one
// test per process under ctest), so no earlier free has moved the threshold.
TEST(CoreMemory, FreedBlocksAreReusedWithoutFaults) {
#if !defined(__GLIBC__)
  GTEST_SKIP() << "keepFreedMemory tunes glibc's malloc";
#endif
  if (kSanitizerAllocator) GTEST_SKIP() << "the sanitizer's allocator replaces malloc";
  prt::keepFreedMemory();
  constexpr size_t kBytes = size_t(16) << 20;
  constexpr long kPages = long(kBytes / 4096);
  const long first = touchFresh(kBytes);
  const long again = touchFresh(kBytes);
  EXPECT_LT(again, kPages / 16) << "faults touching a freed 16 MiB block again (first time: " << first << ")";
}

}  // namespace
