// Adaptive refinement of the baked meshes before the bake (docs/bake.md, "Refinement"): per-
// vertex transfer is interpolated linearly across each triangle, so a shadow edge or a contact
// shadow inside a large triangle is lost. Refinement estimates the shadowed direct transfer at
// the vertices and at candidate points (edge midpoints, triangle centroids) with the bake's own
// estimator, and bisects the edges where it differs from the linear interpolation by more than
// a tolerance, largest errors first, up to a vertex budget (Sloan et al. 2002 baked finely
// tessellated meshes; D3DX's PRT engine subdivided adaptively for the same reason).
#pragma once

#include <cstdint>

#include "prt/bake/checkpoint.h"
#include "prt/bake/surface_bake.h"
#include "prt/scene.h"

namespace prt::bake {

struct RefineSettings {
  /// Largest accepted interpolation error, relative to the norm of the unoccluded transfer
  /// (see refineScene); 0 = no refinement.
  double tolerance = 0.01;
  /// At most this many vertices added, over all instances; 0 = kAutoBudget.
  uint64_t budget = 0;
  /// Directions per point of the refinement's estimate (at most the bake's samples).
  int samples = 128;
};

/// The budget when RefineSettings::budget is 0: as many vertices as the baked instances hold,
/// at least kMinAutoBudget, so refinement at most about doubles the bake's work.
constexpr uint64_t kMinAutoBudget = 10000;
uint64_t refineBudget(const RefineSettings& refine, const Scene& scene);

/// Edges shorter than twice this share of refineScale() are not split: a contact line would
/// otherwise take the whole budget at the floating-point limit.
constexpr double kMinEdgeShare = 1e-3;
/// The share of the baked vertices that refineScale() leaves out at each end of each axis.
constexpr double kScaleOutliers = 0.01;

/// The size refinement measures edges against: the diagonal of the box that holds the baked
/// vertices from the kScaleOutliers quantile to the 1 − kScaleOutliers one along each axis (a
/// level's 2 km ground plane of a few vertices does not make its houses' walls "short"); 0
/// without baked vertices.
double refineScale(const Scene& scene);
/// Rounds of splitting at most (each halves the edges it splits).
constexpr int kMaxRefineRounds = 24;

/// Throws prt::Error on bad values; the message names the field.
void validate(const RefineSettings& s);

struct RefineStats {
  uint64_t verticesBefore = 0, verticesAfter = 0;  // of the baked instances
  uint64_t trianglesBefore = 0, trianglesAfter = 0;
  uint64_t budget = 0;  // the budget used (refineBudget)
  int rounds = 0;       // rounds that split edges
  uint64_t points = 0;  // points estimated
  uint64_t rays = 0;
  bool budgetReached = false;
  /// Largest noise-corrected interpolation error left among the final mesh's candidates,
  /// relative to the unoccluded transfer's norm (the quantity compared with the tolerance).
  double residual = 0.0;
  double seconds = 0.0;
};

/// Adds the refinement settings to a checkpoint fingerprint: refinement runs again on resume
/// (it is deterministic), so a resumed bake must refine the same way.
void addRefineFingerprint(Fingerprint& fp, const RefineSettings& refine, const BakeSettings& bake);

/// Refines the non-receiver instances of `scene` in place. For the shadowed direct transfer t
/// (bands and seed of `bake`, RefineSettings::samples directions) the error at an edge's
/// midpoint m is e = b(m) − (b(a) + b(b))/2, b = t_unoccluded − t the light the scene blocks
/// (so the normals' own interpolation, which any viewer shows, does not count, and an
/// unoccluded surface is left alone whatever its curvature), and at a centroid
/// b(c) − mean of the corners. An edge is split when (|e| − 2σ) / |t_unoccluded| exceeds
/// the tolerance, σ the Monte Carlo standard error of e (noise never splits). Splitting is
/// longest-edge bisection with conforming closure (Rivara): every triangle of a split edge is
/// split at the same new vertex, so no T-junction appears; edges are matched by position, so
/// the two sides of a UV seam or a flat-normal split are split alike. New vertices interpolate
/// positions, normals (renormalised), texture coordinates and colours, and record in
/// MeshInstance::fileBlend the file vertices they interpolate (fileVertex is folded into it).
/// Deterministic for any thread count. Throws prt::Interrupted when interruptRequested()
/// (after `checkpoint->stopIfInterrupted()` saves, if given).
RefineStats refineScene(Scene& scene, const RefineSettings& refine, const BakeSettings& bake,
                        Checkpoint* checkpoint = nullptr);

}  // namespace prt::bake
