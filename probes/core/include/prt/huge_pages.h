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

/// n uninitialised Ts (T trivial) on huge pages: nothing is written, so pages never touched
/// are never faulted in.
template <class T>
std::unique_ptr<T[]> uninitialisedOnHugePages(size_t n) {
  std::unique_ptr<T[]> p(new T[n]);  // default-initialised: left as it is
  adviseHugePages(p.get(), n * sizeof(T));
  return p;
}

}  // namespace prt
