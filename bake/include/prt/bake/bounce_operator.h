// The direct-to-indirect operator (prt/bounce_operator.h): built by the bake from its own rays,
// and evaluated at each light change by `prt render` and `prt relight` (docs/lights.md, "Their
// bounces"). Per light change: the direct light at each cluster (a few shadow rays, or the mean
// of the vertices' own where they are traced), the sky's detail in each sky bin, then sparse
// products: cluster to cluster for the bounces after the first, and one row per vertex side.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "prt/bake/direct_light.h"
#include "prt/bake/surface_bake.h"
#include "prt/bounce_operator.h"
#include "prt/light_rig.h"
#include "prt/probe_grid.h"
#include "prt/scene.h"
#include "prt/sh.h"

namespace prt::bake {

/// The cluster size a bake picks when none is given (OperatorSettings::clusterSize 0): clusters
/// of kSmallClusterSize vertex sides in a scene of at most kSmallScenesSides, else of
/// kLargeClusterSize. A light change costs about the clusters' count (their shadow rays and
/// rows), and the rows' nodes cost more bits as the tree deepens: a small scene affords the finer
/// clusters, which a room's contact shadows and corners need (docs/lights.md, "The bounce
/// operator"), and a large level keeps its light change and its file within bounds.
constexpr int kSmallClusterSize = 4, kLargeClusterSize = 8;
constexpr uint64_t kSmallScenesSides = 262144;

/// The cluster size a bake builds with: `clusterSize` where given (not 0), else the rule above
/// for a scene of `vertexSides`.
int clusterSizeFor(int clusterSize, uint64_t vertexSides);

struct OperatorSettings {
  int samples = 256;           // gather rays per vertex side: the bake's first ones
  int clusterSize = 0;         // vertex sides per cluster, at most; 0: clusterSizeFor's rule
  int rowLength = 0;           // entries of a vertex side's own row (kept where its view is not its cluster's); 0: none
  int clusterRowLength = 96;   // entries of a cluster's row on average (each at most 255)
  int gradientRowLength = 24;  // entries of each of a cluster's two gradient rows, at most; 0: none
  int skyWidth = 32, skyHeight = 16;  // sky bins (equirectangular)
  int samplePoints = 2;               // shadow-ray points per cluster
  int probeSamples = 256;             // gather rays per probe: the probe bake's first ones
  int probeRowLength = 96;            // entries of a probe's row, at most
  int threads = 0;                    // 0 = all cores
};

/// Throws prt::Error unless every field is within its limits (samples 1..16777216, cluster
/// size 0..65536 (0: clusterSizeFor's rule), row lengths 0..255 (a cluster's at least 1), sky bins 1..1024, sample points 1..64).
void validate(const OperatorSettings& s);

/// A probe grid's rows over an operator's nodes with every entry's SH projection in full
/// (the stored rows keep a mean direction instead: BounceOperator::ProbeRows): what tests and
/// measurements compare the stored rows with. Probe p (the grid's order) has the entries
/// [start[p], start[p + 1]), entry e the node node[e] and n² sums sh[e · n² + j] =
/// Σ_rays share · y_j(ω) / N over its rays (N rays per probe).
struct ProbeShRows {
  int bands = 0;
  std::vector<uint32_t> start, node;
  std::vector<float> sh;
};

/// Builds the operator of a baked scene (its meshes as the bake numbers them, refinement done)
/// for `bounces` bounces, tracing `settings.samples` of the bake's rays (seed `seed`) from every
/// vertex side. Deterministic for any thread count. `uncompressed` keeps every leaf a vertex
/// row reaches (rows may then exceed rowLength, and the operator is for tests only: it cannot
/// be stored). `kept`: the bake's own record of those rays (SurfaceTransfer::gather, of
/// settings.samples rays), read instead of tracing them again where it has a side's: the same
/// operator, to the bit. With `probes` (the grid the bake made of this scene) it makes the probes' rows
/// too (BounceOperator::probeRows, from `settings.probeSamples` of each valid probe's own rays,
/// cut to probeRowLength entries unless uncompressed), and `probeSh` (if given) receives the
/// same rows with their SH in full.
BounceOperator buildBounceOperator(const Scene& scene, const OperatorSettings& settings, int bounces, uint64_t seed,
                                   bool uncompressed = false, const ProbeGrid* probes = nullptr,
                                   ProbeShRows* probeSh = nullptr, const GatherRecords* kept = nullptr);

/// Throws prt::Error "WHERE: probe rows: problem" unless op's probe rows belong to `grid`
/// (its lattice, seed and active probes).
void checkProbeRows(const BounceOperator& op, const ProbeGrid& grid, const std::string& where);

/// Adds the operator's bounced light at every probe to `relit` (relightProbes' layout for
/// `grid`): c_p += Σ over probe p's row of its SH share · value(node) / π, `values` the node
/// values of the light change (OperatorLighting::nodeValues). Precondition: op's probe rows
/// belong to grid (checkProbeRows).
void addProbeBounce(const BounceOperator& op, const ProbeGrid& grid, const std::vector<glm::vec3>& values,
                    std::vector<glm::vec3>& relit);
/// The same from rows with their SH in full.
void addProbeBounce(const ProbeShRows& rows, const ProbeGrid& grid, const std::vector<glm::vec3>& values,
                    std::vector<glm::vec3>& relit);

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
  /// Per node of the operator, after light() or lightFrom(): π × the radiance it stands for
  /// (surface nodes: ρ E summed over the bounces, Σ_k R^k; sky nodes: the sky detail).
  std::vector<glm::vec3> nodeValues() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace prt::bake
