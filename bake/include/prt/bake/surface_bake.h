// Per-vertex SH transfer to irradiance, shadowed and interreflected (Sloan et al. 2002).
// What is computed, with every factor of π: docs/prt-math.md.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/checkpoint.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/stats.h"
#include "prt/bake/surface_layout.h"
#include "prt/bake_record.h"
#include "prt/scene.h"

namespace prt::bake {

struct BakeSettings {
  int bands = 3;         // 1 .. sh::kMaxBands
  int samples = 1024;    // directions per vertex (hemisphere, cosine-weighted)
  int bounces = 2;       // 0 = direct shadowed only
  bool shadowed = true;  // false: unshadowed transfer, closed form, no rays
  uint64_t seed = 1;
  int threads = 0;              // 0 = all cores
  bool progress = false;        // progress bar on stderr
  bool keepLowerOrder = false;  // also return the transfer summed to K−1 bounces (for probes)
  /// Also return each vertex side's first keepGatherRays rays as traced (SurfaceTransfer::
  /// gather, for the bounce operator, which then traces none of them again); 0: none. At most
  /// samples; kept only with bounces (the hit records they come from).
  int keepGatherRays = 0;
  /// Memory guard only (bakeSurface ignores it): vertices that refinement (refine.h) may still
  /// add to the scene before the bake, each with two triangles.
  uint64_t refineVertices = 0;
  /// Memory guard only: the bounce operator's probe row length, where it makes probe rows (0:
  /// none).
  int operatorProbeRowLength = 0;
};

/// Throws prt::Error unless 1 <= bands <= sh::kMaxBands ("bands 9: must be between 1 and 8").
/// The one check of an SH band count for every bake setting.
void validateBands(int bands);

/// Limits of BakeSettings and ProbeSettings (validate() checks them): directions per vertex or
/// probe, and bounces.
constexpr int kMaxSamples = 1 << 24;
constexpr int kMaxBounces = 64;

/// Throws prt::Error if a setting is out of range; the message names the field.
void validate(const BakeSettings& s);

/// Each vertex side's first `rays` gather rays as the bake's direct pass traced them (the rays
/// traceGatherRays casts again): per ray whether it escaped and whether it left a hit record
/// (a ray that did neither hit the back of a one-sided face), and those records in ray order,
/// by chunks of `chunk` vertex sides. A chunk this process did not trace (another MPI rank's,
/// or restored from a checkpoint) has no bits.
struct GatherRecords {
  struct Chunk {
    std::vector<uint64_t> bits;   // per side: `words` escape bits, then `words` record bits
    std::vector<uint32_t> begin;  // per side + 1: where its records begin in `hits`
    std::vector<HitRecord> hits;
  };
  uint32_t rays = 0, words = 0;
  size_t chunk = 0;
  std::vector<Chunk> chunks;
  /// Side v's bits (2 · words) and records, or null when they were not kept.
  const Chunk* of(size_t v) const {
    const size_t c = chunk ? v / chunk : 0;
    return c < chunks.size() && !chunks[c].bits.empty() ? &chunks[c] : nullptr;
  }
};

struct SurfaceTransfer {
  int bands = 0;
  /// Per Scene::meshes entry: vertexCount × bands² RGB (empty for receiver-only instances);
  /// for an instance whose back side is baked (bakesBackSide), 2 × vertexCount × bands²: the
  /// front side's vertices, then the back side's (vertex v's back is entry vertexCount + v),
  /// what MeshInstance::transfer and transferBack hold split in two.
  std::vector<std::vector<glm::vec3>> perMesh;
  /// The direct part of perMesh (bounce 0, t⁰: first-hit visibility), colourless: the same
  /// layout with one float per coefficient. For an unshadowed bake, all of the transfer.
  std::vector<std::vector<float>> perMeshDirect;
  /// Same layout, summed over bounces 0 .. K−1 only (empty when K = 0): what a probe must see
  /// on the surfaces so that a receiver at a point is lit as a baked vertex there would be
  /// with K bounces (docs/probes.md). Filled when BakeSettings::keepLowerOrder is set.
  std::vector<std::vector<glm::vec3>> perMeshLowerOrder;
  /// Filled when BakeSettings::keepGatherRays is set (and the bake has bounces).
  GatherRecords gather;
  BakeStats stats;
};

/// Moves SurfaceTransfer::perMesh into the scene's instances: MeshInstance::transfer, and for
/// an instance whose back side was baked, the second half into MeshInstance::transferBack;
/// likewise perMeshDirect (if given) into transferDirect and transferDirectBack.
void storeTransfer(Scene& scene, std::vector<std::vector<glm::vec3>> perMesh,
                   std::vector<std::vector<float>> perMeshDirect = {});

/// Checkpoint stage ids of the surface bake: direct pass 1, bounce k is 1 + k, and the finished
/// surface stage (kept for a probe bake that follows) 2 + bounces. Below kProbeStageFirst.
constexpr uint32_t kSurfaceStageDirect = 1;
constexpr uint32_t kProbeStageFirst = 1000;

struct BakeControl {
  /// Saves progress into it and restores what it holds (null: none). Without one the bake
  /// still stops on interruptRequested(), throwing prt::Interrupted.
  Checkpoint* checkpoint = nullptr;
  /// Called once, before the direct pass, with an upper bound on the share of direct rays
  /// kept as hit records, front faces and double-sided backs (what the hit records will take; exact when the checkpoint
  /// already
  /// holds the direct pass). May throw prt::Error to refuse the bake (memory guard).
  std::function<void(double frontHitShare)> checkMemory;
  /// The BVH to trace, shared with the stages that follow (null: the direct pass builds its
  /// own and frees it before the bounces).
  SharedRayScene* rays = nullptr;
};

/// Bakes transfer for every non-receiver instance of the scene. Deterministic: the same seed
/// gives the same result for any thread count, and a bake resumed from a checkpoint (any
/// thread count, interrupted anywhere) gives the same bits as an uninterrupted one.
/// Throws prt::Interrupted when interruptRequested() (after saving the checkpoint, if any).
SurfaceTransfer bakeSurface(const Scene& scene, const BakeSettings& settings, const BakeControl& control = {});

/// The direct-pass rays of the given baked vertices (global order: instances in scene order,
/// receivers skipped, then the back sides of double-sided instances in scene order), exactly as bakeSurface casts them,
/// `samples` per vertex in order. For
/// benchmarks (the Embree ceiling on the same rays) and tests. `rays` is the scene's RayScene
/// (its extent lifts the origins; it moves buried ones out, unbury.h).
std::vector<Ray> surfaceBakeRays(const Scene& scene, const BakeSettings& settings, const RayScene& rays,
                                 const std::vector<size_t>& vertices);

/// The record of a bake with these settings, as a baked file stores it (asset.extras.prt):
/// `sceneName` is the scene's file name, `prtVersion` the prt that bakes.
BakeRecord bakeRecord(const BakeSettings& settings, const std::string& sceneName, const std::string& prtVersion);

}  // namespace prt::bake
