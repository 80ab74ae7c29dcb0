// Probe transfer: at points in space, the matrix M with incident radiance SH c = M · l
// (docs/prt-math.md, docs/probes.md). Needs the surface transfer of the static scene, since a
// ray that hits a surface sees that surface's exitant radiance.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/checkpoint.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/stats.h"
#include "prt/bake/surface_bake.h"
#include "prt/probe_grid.h"
#include "prt/scene.h"

namespace prt::bake {

struct ProbeSettings {
  int bands = 3;
  int samples = 1024;  // uniform sphere directions per probe
  int bounces = 2;     // as the surface bake's (recorded in the file)
  uint64_t seed = 1;
  double spacing = 0.0;                            // > 0: probe spacing in world units
  glm::ivec3 dims{0};                              // or: probe counts per axis (used when spacing == 0)
  std::optional<glm::dvec3> boundsMin, boundsMax;  // default: the scene's bounds
  bool progress = false;
  int threads = 0;  // 0 = all cores
  /// A probe whose rays hit back faces for more than this share is inside geometry.
  double insideThreshold = 0.25;
  /// Where probes are baked (docs/probes.md, "Where probes go"):
  /// - Everywhere: every lattice point outside solid geometry;
  /// - Inside: only free space sealed from the outside of the lattice by the scene's surfaces
  ///   (the inside of a closed level), found by a flood fill through free lattice points;
  /// - Auto: the free points near a surface (a hit within 2 spacings) or surrounded (surfaces
  ///   fill more than 20% of the sphere around them), and their neighbours: open air far from
  ///   everything is left out (the void around a floating level, the sky high above a town);
  ///   a scene with no surface near the lattice keeps every point. A surrounded point under
  ///   open sky (its ray straight up, +Y, escapes) is kept only within `maxHeight` of the
  ///   surface below it: the void above a roofless level, where no receiver goes.
  enum class Region { Auto, Everywhere, Inside };
  Region region = Region::Auto;
  /// Auto: how high above the surface below it a surrounded point under open sky is kept, in
  /// world units (glTF: metres); 0 = no limit.
  double maxHeight = 4.0;
};

/// Throws prt::Error on bad values; the message names the field ("probe spacing: ...").
void validate(const ProbeSettings& s);

/// The bounds the probe lattice fills: s.boundsMin/Max if given, else the scene's bounds with
/// every flat axis (thinner than 1/1000 of the largest extent, e.g. a floor plane's height)
/// padded symmetrically to the largest extent. Throws prt::Error if the scene is a point.
void probeBounds(const ProbeSettings& s, const Scene& scene, glm::dvec3& lo, glm::dvec3& hi);

/// The lattice (origin, spacing, dims) for these settings and scene bounds. Probes sit at cell
/// centres of the bounds, so they are never exactly on the bounding walls.
void layoutGrid(const ProbeSettings& s, const glm::dvec3& lo, const glm::dvec3& hi, ProbeGrid& grid);

/// Checkpoint stage of the probe bake: lattice points in chunks of kProbeChunk, in lattice
/// order (whatever the thread count); a chunk record holds its points' results as they go
/// into the grid.
constexpr uint32_t kProbeStage = kProbeStageFirst;
constexpr size_t kProbeChunk = 64;

/// Adds every setting that changes the probe stage's results to a checkpoint fingerprint
/// (bands, samples, bounces, seed, spacing or dims, bounds, inside threshold, region). The scene's
/// own entries come from addSceneFingerprint.
void addProbeFingerprint(Fingerprint& fp, const ProbeSettings& settings);

/// What the probe placement (docs/probes.md, "Where probes go") keeps of a lattice, counted for
/// the memory guard (memory_estimate.h): the points it bakes, and bounds on the active probes
/// (the valid ones and their neighbours, so within one lattice step of a baked point) and on
/// the OpenVDB blocks that hold them.
struct ProbePlacement {
  uint64_t points = 0;       // lattice points
  uint64_t baked = 0;        // not left out: each may keep a transfer record
  uint64_t activeBound = 0;  // points within one step (of the 26 around) of a baked point, or baked
  uint64_t leafBlocks = 0;   // 8³ blocks of the lattice (from its origin) holding such a point
  uint64_t lowerBlocks = 0;  // 128³ blocks likewise
};

/// The placement bakeProbes makes for these settings, on a BVH of its own, in this process
/// alone (no MPI exchange: every rank that calls it gets the same answer). About
/// kProbeTestRays (64) rays per lattice point. Throws prt::Interrupted if interrupted.
ProbePlacement placeProbes(const Scene& scene, const ProbeSettings& settings);

/// Bakes the probe grid. `lowerOrder[k]` is instance k's surface transfer summed over bounces
/// 0..K−1 (SurfaceTransfer::perMeshLowerOrder; empty vectors when K = 0; both sides, front
/// then back, for an instance whose back side is baked), so a receiver at a point is lit like
/// a baked vertex there with K bounces. A ray hitting the back of a double-sided face gathers
/// the back side's transfer. Deterministic for any thread count.
/// With a checkpoint: restores the chunks it holds, saves finished ones (its interval, and on
/// interrupt), and the result has the same bits as an uninterrupted bake. Throws
/// prt::Interrupted within about a second of interruptRequested() (after saving, if any).
ProbeGrid bakeProbes(const Scene& scene, const std::vector<std::vector<glm::vec3>>& lowerOrder,
                     const ProbeSettings& settings, ProbeStats* stats = nullptr, Checkpoint* checkpoint = nullptr,
                     SharedRayScene* rays = nullptr);  // null: builds its own; else traces it and releases it

/// A set of rays bakeProbes casts from lattice point `lattice` (linear index x + dims.x·(y +
/// dims.y·z) into layout.dims, lattice from layoutGrid), from the point itself (candidate −1)
/// or from relocation candidate `candidate`'s position.
struct ProbeRaySet {
  uint64_t lattice = 0;
  int candidate = -1;
};

/// The ray sets a bake of `points` lattice points cast, as `stats` (ProbeStats::traced) tells
/// them: into `tests` every point's inside test and its relocation candidates' tests, in lattice
/// order; into `fulls` the full sets, from the point or from the last candidate it tested (the
/// one it moved to). Their rays, 64 per test and settings.samples per full set, are stats.rays.
void probeRaySets(const ProbeStats& stats, uint64_t points, std::vector<ProbeRaySet>& tests,
                  std::vector<ProbeRaySet>& fulls);

/// The 64-ray inside tests of `sets` (the point's quick test, or a relocation candidate's),
/// 64 rays each, in the bake's order; untraced. For benchmarks (with ProbeStats::traced).
std::vector<Ray> probeTestRays(const ProbeGrid& layout, const ProbeSettings& settings,
                               const std::vector<ProbeRaySet>& sets);

/// The full sets of `sets` (settings.samples rays each, from the point or the candidate it moved
/// to), in the bake's order; untraced. For benchmarks (with ProbeStats::traced).
std::vector<Ray> probeFullRays(const ProbeGrid& layout, const ProbeSettings& settings,
                               const std::vector<ProbeRaySet>& sets);

}  // namespace prt::bake
