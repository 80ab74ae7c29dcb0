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

namespace prt {

/// Asks the kernel to back the 2 MiB-aligned part of [p, p + bytes) with transparent huge pages
/// (madvise MADV_HUGEPAGE). Advice only: nothing happens for ranges shorter than a huge page,
/// without the kernel's support or where it is refused, and the contents are unchanged.
void adviseHugePages(void* p, size_t bytes);

/// Maps [p, p + bytes) in now, writable, as a first write would (madvise MADV_POPULATE_WRITE,
/// Linux 5.14 on; elsewhere nothing): threads that call it on parts of an array fault it in
/// side by side, where one thread's first writes would fault it page by page alone. Contents
/// are unchanged (fresh memory reads zero).
void populatePages(void* p, size_t bytes);

/// Sets up glibc's heap for few page faults (elsewhere nothing); called once, first thing in
/// main.
/// - Freed memory stays for the process's next allocations instead of going back to the kernel
///   to be faulted in again. By default glibc maps every block above 128 KiB on its own (a
///   threshold that grows to at most 32 MiB as such blocks are freed) and unmaps it on free,
///   and returns the top of its heap once 128 KiB of it is free: the 81 OpenVDB trees of a
///   probe grid (a 512 KiB node each) were fresh pages every time. Here blocks below 32 MiB
///   come from the heap and up to 512 MiB of free heap is kept; larger blocks (a big scene's
///   per-vertex arrays) are still mapped alone and returned when freed.
/// - The heap's next 256 MiB are reserved at once (address space only) and advised onto huge
///   pages, so that the heap's memory is faulted in 2 MiB at a time: a bake's hit records and
///   the probe grid's trees, 23 k faults on each MPI rank of the default bake, took 2.5 k.
///   Where that reservation is refused (strict overcommit), the heap grows as glibc's does.
void tuneHeap();

}  // namespace prt
