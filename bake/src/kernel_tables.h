// One phase's kernels per instruction set, and the one place that picks the entry in use
// (prt/bake/kernels.h).
#pragma once

#include "prt/bake/kernels.h"

namespace prt::bake {

/// A phase's table of kernels (a struct of function pointers) for each set: every entry gives
/// the same bits as the portable one.
template <class Table>
struct KernelTables {
  Table portable, avx2, avx512;
  /// The entry of set k (not Auto).
  const Table& of(Kernels k) const {
    switch (k) {
      case Kernels::Avx512:
        return avx512;
      case Kernels::Avx2:
        return avx2;
      default:
        return portable;
    }
  }
  /// The entry of the set in use (activeKernels).
  const Table& active() const { return of(activeKernels()); }
};

}  // namespace prt::bake
