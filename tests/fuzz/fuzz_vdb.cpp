// libFuzzer target: prt probe grids (OpenVDB) through readProbeGrid. Any outcome but a grid
// or a prt::Error is a bug (docs/robustness.md).
#include "fuzz_file.h"
#include "prt/error.h"
#include "prt/probe_grid.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static prt::fuzz::MemoryFile file("fuzz_vdb");
  try {
    prt::ProbeGrid grid = prt::readProbeGrid(file.set(data, size));
    // What the reader promises: parallel arrays, probes inside dims and found by the index.
    if (grid.transfer.size() != grid.probeCount() * grid.transferStride()) __builtin_trap();
    for (size_t p = 0; p < grid.probeCount(); ++p)
      if (grid.find(grid.coord[p]) != int(p)) __builtin_trap();
  } catch (const prt::Error&) {
  }
  return 0;
}
