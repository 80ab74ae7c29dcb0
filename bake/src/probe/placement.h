// Where probes go (ProbeSettings::region, docs/probes.md "Where probes go"): the quick inside
// test of every lattice point, which points are baked, and where a point inside geometry may
// move (placement.cpp).
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/probe_bake.h"
#include "prt/probe_grid.h"

namespace prt::bake::probe {

struct Tracer;

struct LatticeRegion {
  std::vector<uint8_t> free;  // per lattice point: the quick test passed
  std::vector<uint8_t> skip;  // per lattice point: not baked
  uint64_t freeCount = 0, sealed = 0, outside = 0, aboveLevel = 0;
  bool insideOnly = false;  // only sealed space is kept
  uint64_t rays = 0;
  bool interrupted = false;  // an interrupt was requested before the quick tests finished
};

// The lattice's region (the comment above kNearSpacings in placement.cpp): every point's quick
// test, then which points are baked. MPI ranks share the tests unless `alone` (this process tests
// every point itself: placeProbes).
LatticeRegion classifyLattice(const Tracer& tracer, const ProbeGrid& grid, const ProbeSettings& settings,
                              bool alone = false);

// Relocation candidates, in a fixed order, as fractions of the spacing: along the axes, then
// towards the corners; all inside the probe's cell.
std::vector<glm::dvec3> relocationCandidates();

}  // namespace prt::bake::probe
