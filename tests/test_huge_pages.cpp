// prt/huge_pages.h: memory that is freed is reused without faulting it in again, and the heap
// is advised onto huge pages.
#include <gtest/gtest.h>

#include <sys/mman.h>
#include <sys/resource.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include "harness.h"
#include "prt/huge_pages.h"

namespace {

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

// The VmFlags line of the mapping of /proc/self/smaps that holds `p` (empty: none found).
std::string vmFlagsOf(const void* p) {
  std::ifstream smaps("/proc/self/smaps");
  const auto at = reinterpret_cast<uintptr_t>(p);
  bool inside = false;
  for (std::string line; std::getline(smaps, line);) {
    uintptr_t lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-' && line.find(' ') != std::string::npos &&
        line.find(':') > line.find(' ')) {
      inside = lo <= at && at < hi;
      continue;
    }
    if (inside && line.rfind("VmFlags:", 0) == 0) return line;
  }
  return {};
}

// A 16 MiB block is above glibc's default threshold for a block mapped on its own (128 KiB, and
// it only grows as such blocks are freed): without tuneHeap it is unmapped when freed and every
// one of its 4096 pages faults again the next time. This runs first in its process (one test
// per process under ctest), so no earlier free has moved the threshold.
TEST(CoreMemory, FreedBlocksAreReusedWithoutFaults) {
#if !defined(__GLIBC__)
  GTEST_SKIP() << "tuneHeap tunes glibc's malloc";
#endif
  if (prt::test::kAddressSanitizer) GTEST_SKIP() << "the sanitizer's allocator replaces malloc";
  prt::tuneHeap();
  constexpr size_t kBytes = size_t(16) << 20;
  constexpr long kPages = long(kBytes / 4096);
  const long first = touchFresh(kBytes);
  const long again = touchFresh(kBytes);
  EXPECT_LT(again, kPages / 16) << "faults touching a freed 16 MiB block again (first time: " << first << ")";
}

// The heap's next 256 MiB are advised onto huge pages (VmFlags "hg", MADV_HUGEPAGE): whether
// the kernel then gives 2 MiB pages depends on the machine, the advice does not.
TEST(CoreMemory, TheHeapIsAdvisedOntoHugePages) {
#if !defined(__GLIBC__) || !defined(MADV_HUGEPAGE)
  GTEST_SKIP() << "tuneHeap tunes glibc's malloc on Linux";
#endif
  if (prt::test::kAddressSanitizer) GTEST_SKIP() << "the sanitizer's allocator replaces malloc";
  if (!std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled")) GTEST_SKIP() << "no transparent huge pages";
  prt::tuneHeap();
  std::unique_ptr<char[]> p(new char[size_t(8) << 20]);  // from the heap (below 32 MiB)
  asm volatile("" : : "r"(p.get()) : "memory");
  const std::string flags = vmFlagsOf(p.get() + (size_t(4) << 20));
  ASSERT_FALSE(flags.empty()) << "no mapping holds the block";
  EXPECT_NE(flags.find(" hg"), std::string::npos) << flags;
}

}  // namespace
