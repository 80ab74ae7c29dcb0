// Large arrays on transparent huge pages.
//
// Fresh memory is mapped on first touch, one fault per page. Where the kernel gives huge pages
// only on request (/sys/kernel/mm/transparent_hugepage/enabled = madvise: these machines, and
// common distribution kernels), an array is faulted in 4 KiB at a time; on the VMs prt is
// measured on a fault costs ~12 µs, so touching a fresh 38 MB array took 112 ms, against 3 ms on
// 2 MiB pages (docs/bake.md, "Page faults"). Bakes that fill such arrays ask for huge pages.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

namespace prt {

/// Asks the kernel to back the 2 MiB-aligned part of [p, p + bytes) with transparent huge pages
/// (madvise MADV_HUGEPAGE). Advice only: nothing happens for ranges shorter than a huge page,
/// without the kernel's support or where it is refused, and the contents are unchanged.
void adviseHugePages(void* p, size_t bytes);

/// v.resize(n), the new storage advised onto huge pages before it is first touched.
/// Precondition: v is empty (nothing to move).
template <class T>
void resizeOnHugePages(std::vector<T>& v, size_t n) {
  v.reserve(n);
  adviseHugePages(v.data(), n * sizeof(T));
  v.resize(n);
}

/// Keeps memory the process frees for its own next allocations, instead of handing it back to
/// the kernel and faulting it in again (glibc; elsewhere nothing). By default glibc maps every
/// block above 128 KiB on its own (a threshold that grows to at most 32 MiB as such blocks are
/// freed) and unmaps it on free, and it returns the top of its heap once 128 KiB of it is free:
/// the 81 OpenVDB trees of a probe grid (a 512 KiB node each) were fresh pages every time.
/// After this, blocks below 32 MiB come from the heap, and up to 256 MiB of free heap is kept.
/// Larger blocks (a big scene's per-vertex arrays) are still mapped alone and returned when
/// freed. Called once, first thing in main.
void keepFreedMemory();

/// n uninitialised Ts (T trivial) on huge pages: nothing is written, so pages never touched
/// are never faulted in.
template <class T>
std::unique_ptr<T[]> uninitialisedOnHugePages(size_t n) {
  std::unique_ptr<T[]> p(new T[n]);  // default-initialised: left as it is
  adviseHugePages(p.get(), n * sizeof(T));
  return p;
}

}  // namespace prt
