#include "prt/huge_pages.h"

#include <cstdint>
#include <cstdlib>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif
#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace prt {

void adviseHugePages(void* p, size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr uintptr_t kHuge = uintptr_t(2) << 20;
  const uintptr_t begin = (reinterpret_cast<uintptr_t>(p) + kHuge - 1) & ~(kHuge - 1);
  const uintptr_t end = (reinterpret_cast<uintptr_t>(p) + bytes) & ~(kHuge - 1);
  if (p && end > begin) (void)madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#else
  (void)p;
  (void)bytes;
#endif
}

void populatePages(void* p, size_t bytes) {
#if defined(__linux__)
  constexpr int kPopulateWrite = 23;  // MADV_POPULATE_WRITE, where the headers predate it
  constexpr uintptr_t kPage = 4096;
  const uintptr_t begin = reinterpret_cast<uintptr_t>(p) & ~(kPage - 1);
  const uintptr_t end = reinterpret_cast<uintptr_t>(p) + bytes;
  if (p && end > begin) (void)madvise(reinterpret_cast<void*>(begin), end - begin, kPopulateWrite);  // advice only
#else
  (void)p;
  (void)bytes;
#endif
}

void tuneHeap() {
#if defined(__GLIBC__)
  // Setting a threshold turns off glibc's sliding ones, so both are set.
  (void)mallopt(M_MMAP_THRESHOLD, 32 << 20);
  (void)mallopt(M_TRIM_THRESHOLD, 512 << 20);  // above the reservation: it is never trimmed
  // The reservation: one allocation that grows the heap by 256 MiB more than it needs (glibc's
  // top pad), advised onto huge pages, then freed into the heap's top, which stays.
  constexpr int kReserve = 256 << 20;
  (void)mallopt(M_TOP_PAD, kReserve);
  char* before = static_cast<char*>(sbrk(0));
  void* p = std::malloc(size_t(1) << 20);
  char* after = static_cast<char*>(sbrk(0));
  (void)mallopt(M_TOP_PAD, 128 << 10);  // glibc's default for the heap's growth from here on
  if (p && before != reinterpret_cast<char*>(-1) && after > before) adviseHugePages(before, size_t(after - before));
  std::free(p);
#endif
}

}  // namespace prt
