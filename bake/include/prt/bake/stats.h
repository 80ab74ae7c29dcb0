// What a bake reports of itself: the surface bake's stages (BakeStats) and the probe bake's
// (ProbeStats), plain data, for the summaries, the benchmarks and the stage runner.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace prt::bake {

struct StageStats {
  std::string name;  // "direct", "bounce 1", ...
  double seconds = 0.0;
  uint64_t rays = 0;
  // The direct pass: time inside Embree's calls, all threads of this process together (so up to
  // threads × seconds), measured in the bake (prt_bench_bake's share not tracing).
  double traceSeconds = 0.0;
};

struct BakeStats {
  uint64_t vertices = 0;
  uint64_t backVertices = 0;  // back sides baked (vertices of double-sided instances)
  uint64_t rays = 0;          // cast by this run (a resumed bake casts only what was left)
  bool resumed = false;       // continued from a checkpoint
  uint64_t hitRecords = 0;    // rays that hit a front face or a double-sided back (kept for the bounces)
  double seconds = 0.0;
  std::vector<StageStats> stages;
};

struct ProbeStats {
  uint64_t probes = 0;      // lattice points
  uint64_t active = 0;      // stored
  uint64_t invalid = 0;     // inside geometry, not moved out
  uint64_t moved = 0;       // moved out of geometry within their cell
  uint64_t outside = 0;     // free lattice points not baked (open air, or outside a closed level)
  uint64_t aboveLevel = 0;  // of them: surrounded, but under open sky above maxHeight (Auto)
  uint64_t sealed = 0;      // free lattice points sealed inside the scene's surfaces
  bool insideOnly = false;  // only sealed space was baked (a closed level)
  uint64_t valid = 0;       // stored with transfer
  uint64_t rays = 0;        // cast by this run: inside tests, relocation candidates, full sets
  /// What this run traced from each lattice point beyond its inside test, in lattice order (the
  /// points skipped after their test are not listed; on rank 0 of an MPI bake): for benchmarks,
  /// which regenerate the rays with probeTestRays and probeFullRays.
  struct Traced {
    uint64_t lattice = 0;
    uint32_t candidates = 0;  // relocation candidates tested, in the bake's order (64 rays each)
    bool full = false;        // the full set traced: from the point, or from the last candidate (moved)
  };
  std::vector<Traced> traced;
  uint64_t restored = 0;  // lattice points restored from the checkpoint (not traced again)
  double seconds = 0.0;
  // Inside Embree's calls, all threads of this process together (so up to threads × seconds):
  // what of the bake is tracing, measured in the bake itself (prt_bench_probes).
  double traceSeconds = 0.0;
  // Inside the lit hits' gather (the light of the lit surfaces a probe's rays hit: their
  // corners' transfer interpolated, times the ray's SH values), all threads together: the probe
  // bake's counterpart of the surface bake's bounces, which it does per ray instead of as stages
  // of its own (prt_bench_probes reports the bake with and without it).
  double gatherSeconds = 0.0;
};

}  // namespace prt::bake
