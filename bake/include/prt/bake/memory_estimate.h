// Memory guard for `prt bake`: an upper bound on the peak resident memory of a bake, from the
// loaded scene and the settings, checked against the memory available before the work starts
// (docs/bake.md, "Memory"). The model and its measured constants are in memory_estimate.cpp.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "prt/bake/probe_bake.h"
#include "prt/bake/surface_bake.h"
#include "prt/scene.h"

namespace prt::bake {

struct MemoryEstimate {
  // Parts of the peak, in bytes (the peak is the largest phase, not the sum of the parts).
  uint64_t base = 0;           // the process itself: code, libraries, thread stacks
  uint64_t scene = 0;          // the loaded scene (geometry, textures)
  uint64_t bvh = 0;            // Embree's copy of the geometry and its BVH
  uint64_t hits = 0;           // hit records of the direct pass (for the bounces)
  uint64_t transfer = 0;       // one per-vertex transfer buffer (vertices × bands² × 12)
  uint64_t probes = 0;         // probe bake: the lattice's slots and transfer (its part that scales)
  double frontHitShare = 1.0;  // share of direct rays assumed to hit a front face
  /// The probe placement counted, where it was measured (placeProbes); else every lattice point
  /// counts as baked and active.
  std::optional<ProbePlacement> placement;
  // Peaks of the phases.
  uint64_t surfacePeak = 0, probePeak = 0, writePeak = 0;
  uint64_t refinePeak = 0;  // refinement (BakeSettings::refineVertices > 0), before the bake
  uint64_t total = 0;       // max of the phase peaks

  /// Adds a refinement phase measured before (estimated with BakeSettings::refineVertices) to
  /// an estimate of the refined scene, so that it bounds the whole run.
  void keepRefinePhase(uint64_t peak);
  /// "1.2 GiB (hit records 900 MiB, transfer 3 × 40 MiB, BVH 80 MiB, scene 30 MiB, ...)".
  std::string describe() const;
  /// "surface 150 MiB, probes 180 MiB, write 120 MiB": each phase's peak with the base and
  /// slack, i.e. what the estimate would be if that phase were the largest.
  std::string phases() const;
};

/// The bound for this scene and these settings; `probes` null when no probe grid is baked.
/// `frontHitShare` bounds the share of direct rays that hit a front face (1 = worst case:
/// every ray leaves a hit record). `placement` (placeProbes for these probe settings) counts
/// only the lattice points the probe bake keeps; null: all of them (the worst case).
MemoryEstimate estimateBakeMemory(const Scene& scene, const BakeSettings& settings, const ProbeSettings* probes,
                                  double frontHitShare, const ProbePlacement* placement = nullptr);

struct MemoryLimit {
  uint64_t bytes = 0;
  /// What set it: kGivenLimit (a limit the caller gave), "the available memory (MemAvailable)",
  /// "the cgroup limit (memory.max)".
  std::string source;
};
/// MemoryLimit::source of a limit given to memoryLimit() (a tool names its own option instead).
inline constexpr const char* kGivenLimit = "the given limit";

/// Ways to make a refused bake fit, each alone enough: the largest power-of-two sample count
/// that fits, else a coarser probe lattice, else fewer bands. None set: only a higher limit
/// (above the estimate) helps.
struct MemoryAdvice {
  std::optional<int> samples;
  std::optional<ProbeSettings> probes;  // the same settings with a coarser spacing or dims
  std::optional<int> bands;
};

/// The memory this process may use: `maxMemory` if given, else what the system has available
/// (MemAvailable from /proc/meminfo, and the cgroup v2/v1 limit if one is set) plus what
/// this process already holds. nullopt when nothing can be read.
std::optional<MemoryLimit> memoryLimit(std::optional<uint64_t> maxMemory);

/// Parses "8G", "500M", "64k", "1.5GiB", "123456" (bytes; k/M/G/T are powers of 1024).
/// Throws prt::Error naming `option` on anything else.
uint64_t parseByteSize(const std::string& text, const std::string& option);

/// nullopt when the estimate fits the limit; else the settings that would fit.
std::optional<MemoryAdvice> memoryShortfall(const MemoryEstimate& estimate, const MemoryLimit& limit,
                                            const Scene& scene, const BakeSettings& settings,
                                            const ProbeSettings* probes);

/// How checkMemory's refusal names the settings: the fields by default ("samples 256"); a tool
/// passes its options ("--samples 256", "raise --max-memory", "--max-memory" for kGivenLimit).
struct MemoryAdviceNames {
  std::string samples = "samples", probeSpacing = "probe spacing", probeDims = "probe dims", bands = "bands";
  std::string raiseLimit = "raise the limit";
  std::string givenLimit = kGivenLimit;
};

/// Throws prt::Error when the estimate exceeds the limit: one line with the estimate, the
/// limit and the advice of memoryShortfall, in `names`.
void checkMemory(const MemoryEstimate& estimate, const MemoryLimit& limit, const Scene& scene,
                 const BakeSettings& settings, const ProbeSettings* probes, const MemoryAdviceNames& names = {});

}  // namespace prt::bake
