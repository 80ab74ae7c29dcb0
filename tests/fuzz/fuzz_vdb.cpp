// libFuzzer target: prt probe grids (OpenVDB) through readProbeGrid. Any outcome but a grid
// or a prt::Error is a bug (docs/robustness.md).
#include <cstdlib>
#include <new>

#include "fuzz_file.h"
#include "prt/error.h"
#include "prt/probe_grid.h"

// OpenVDB allocates whatever a corrupt size field says (bloscFromStream: new char[size])
// before reading the bytes. prt's walk of the file (probes/grid/src/vdb_layout.h) refuses such
// sizes first; should one get through, in a normal build an impossible size throws std::bad_alloc, which
// prt reports as a corrupt file; ASan's operator new aborts instead. These replacements give
// back the standard behaviour on top of ASan's malloc (run with allocator_may_return_null=1
// and alloc_dealloc_mismatch=0, as tests/fuzz/run.sh does), so the fuzzer tests what users get.
void* operator new(std::size_t n) {
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static prt::fuzz::MemoryFile file("fuzz_vdb");
  try {
    prt::ProbeGrid grid = prt::readProbeGrid(file.set(data, size));
    // What the reader promises: parallel arrays, probes inside dims and found by the index.
    if (grid.transfer.size() != grid.probeCount() * grid.transferStride()) __builtin_trap();
    for (size_t p = 0; p < grid.probeCount(); ++p)
      if (grid.find(grid.coord[p]) != int(p)) __builtin_trap();
  } catch (const prt::Error&) {}
  return 0;
}
