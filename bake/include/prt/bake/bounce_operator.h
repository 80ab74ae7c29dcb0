// The direct-to-indirect operator (prt/bounce_operator.h): built by the bake from its own rays,
// and evaluated at each light change by `prt render` and `prt relight` (docs/lights.md, "Their
// bounces"). Per light change: the direct light at each cluster (a few shadow rays, or the mean
// of the vertices' own where they are traced), the sky's detail in each sky bin, then sparse
// products: cluster to cluster for the bounces after the first, and one row per vertex side.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "prt/bake/direct_light.h"
#include "prt/bake/surface_bake.h"
#include "prt/bounce_operator.h"
#include "prt/light_rig.h"
#include "prt/scene.h"
#include "prt/sh.h"

namespace prt::bake {

struct OperatorSettings {
  int samples = 256;           // gather rays per vertex side: the bake's first ones
  int clusterSize = 8;         // vertex sides per cluster, at most
  int rowLength = 0;           // entries of a vertex side's own row (kept where its view is not its cluster's); 0: none
  int clusterRowLength = 96;   // entries of a cluster's row, at most
  int gradientRowLength = 24;  // entries of each of a cluster's two gradient rows, at most; 0: none
  int skyWidth = 32, skyHeight = 16;  // sky bins (equirectangular)
  int samplePoints = 4;               // shadow-ray points per cluster
  int threads = 0;                    // 0 = all cores
};

/// Throws prt::Error unless every field is within its limits (samples 1..16777216, cluster
/// size 1..65536, row lengths 0..255 (a cluster's at least 1), sky bins 1..1024, sample points 1..64).
void validate(const OperatorSettings& s);

/// Builds the operator of a baked scene (its meshes as the bake numbers them, refinement done)
/// for `bounces` bounces, tracing `settings.samples` of the bake's rays (seed `seed`) from every
/// vertex side. Deterministic for any thread count. `uncompressed` keeps every leaf a vertex
/// row reaches (rows may then exceed rowLength, and the operator is for tests only: it cannot
/// be stored). `kept`: the bake's own record of those rays (SurfaceTransfer::gather, of
/// settings.samples rays), read instead of tracing them again where it has a side's: the same
/// operator, to the bit.
BounceOperator buildBounceOperator(const Scene& scene, const OperatorSettings& settings, int bounces, uint64_t seed,
                                   bool uncompressed = false, const GatherRecords* kept = nullptr);

/// What one light change costs, by part.
struct OperatorTimes {
  double sky = 0.0, shadows = 0.0, clusters = 0.0, vertices = 0.0;  // seconds
  uint64_t shadowRays = 0;
};

/// Evaluates an operator at light changes. The scene and operator must outlive it.
class OperatorLighting {
 public:
  /// `traceShadows`: build the static scene's rays for light() (shadow rays at the clusters'
  /// sample points); off, only lightFrom() may be called.
  OperatorLighting(const Scene& scene, const BounceOperator& op, bool traceShadows, int threads = 0);
  ~OperatorLighting();
  OperatorLighting(const OperatorLighting&) = delete;
  OperatorLighting& operator=(const OperatorLighting&) = delete;

  /// Per instance and side (DirectIrradiance's layout): the bounced light of `lights` (their
  /// shadowed light at each cluster, one shadow ray per light and sample point) and of the sky
  /// detail, plus the sky detail's own light Δ (docs/lights.md, "Sky detail"): E_b + Δ. `sky`
  /// null: no sky detail; else `sky` is the radiance `sh` stands for (LightRig::shRadiance).
  /// `directSh` (the lights' SH, RigLighting::directSh; null: none) makes the transfer carry
  /// what it can: the bounces of the lights' SH light t⁰ · directSh are the bake's own
  /// (t − t⁰) · directSh, exact at every vertex, and only the rest, E⁰ − t⁰ · directSh, goes
  /// through the operator (a control variate: docs/lights.md, "The bounce operator").
  DirectIrradiance light(const std::vector<DirectLight>& lights, const sh::ShRgb* directSh, const RigBackground* sky,
                         const sh::ShRgb& sh);
  /// The same with the direct light known at every vertex side (`e0`, shadowedDirectIrradiance's
  /// layout): a cluster's is its members' area-weighted mean.
  DirectIrradiance lightFrom(const DirectIrradiance& e0, const sh::ShRgb* directSh, const RigBackground* sky,
                             const sh::ShRgb& sh);

  const OperatorTimes& lastTimes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace prt::bake
