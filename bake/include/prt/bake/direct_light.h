// The exact light of direct lights (suns, small disks) at baked vertices: their unoccluded
// irradiance over the cap (clipped by the horizon) times the share of it that shadow rays find
// unblocked. With the transfer's direct part this replaces the band-limited sun
// (docs/lights.md, "Direct lights").
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/ray_scene.h"
#include "prt/light.h"
#include "prt/light_rig.h"
#include "prt/scene.h"
#include "prt/sh.h"

namespace prt::bake {

struct ShadowSettings {
  int samples = 64;   // shadow rays per light and vertex, stratified over the cap (1 for a delta)
  uint64_t seed = 1;  // scrambles the strata; the result depends on it, not on threads
  int threads = 0;    // 0 = all cores
};

/// Throws prt::Error unless 1 <= samples <= 65536 ("shadow samples 0: ...").
void validate(const ShadowSettings& s);

struct DirectIrradiance {
  /// Per Scene::meshes entry, per vertex: Σ_k E_k · directCosineFactor_k(n) · visible share,
  /// RGB; empty for instances without transfer. `back`: the back sides of instances with
  /// back-side transfer (normal −n), empty for the others.
  std::vector<std::vector<glm::vec3>> front, back;
  uint64_t rays = 0;
  double seconds = 0.0;
};

/// a += b, instance by instance and side by side; b's empty vectors add nothing.
void addIrradiance(DirectIrradiance& a, const DirectIrradiance& b);

/// Shadowed irradiance of `lights` at every vertex of every instance that holds transfer (the
/// baked ones), traced against the scene's non-receiver instances from the origins the bake's
/// rays leave from (lifted off the surface as in the bake). Visible share: the cosine-weighted
/// mean visibility of `samples` directions stratified uniformly over the cap (Sobol, scrambled
/// per vertex and light), a ratio estimator that is exact wherever nothing occludes the cap.
/// Deterministic for any thread count.
DirectIrradiance shadowedDirectIrradiance(const Scene& scene, const std::vector<DirectLight>& lights,
                                          const ShadowSettings& settings = {});
/// The same traced against `rays` (built from `scene`), for callers that light many frames;
/// `origins` (if given) the vertex sides' ray origins, which such a caller keeps (every baked
/// instance's vertices in scene order, then the back sides: the bake's numbering).
DirectIrradiance shadowedDirectIrradiance(const Scene& scene, const RayScene& rays,
                                          const std::vector<DirectLight>& lights, const ShadowSettings& settings = {},
                                          const std::vector<glm::vec3>* origins = nullptr);

/// The same at arbitrary points `points` with unit normals `normals` (a probe query, `prt
/// probe --scene`): rays leave each point lifted by 10⁻⁴ of the scene's extent along its
/// normal; point i's strata are scrambled by i. Deterministic for any thread count.
std::vector<glm::vec3> shadowedDirectIrradianceAt(const Scene& scene, const std::vector<glm::vec3>& points,
                                                  const std::vector<glm::vec3>& normals,
                                                  const std::vector<DirectLight>& lights,
                                                  const ShadowSettings& settings = {});
/// The same traced against `rays` (built from the scene), for callers that query many times.
std::vector<glm::vec3> shadowedDirectIrradianceAt(const RayScene& rays, std::span<const glm::vec3> points,
                                                  std::span<const glm::vec3> normals,
                                                  const std::vector<DirectLight>& lights,
                                                  const ShadowSettings& settings = {});

struct BounceSettings {
  int samples = 256;  // gather rays per vertex and side: the first of the bake's own rays
  int bounces = 2;    // the bake's count (its record), so direct lights bounce as often as the sky
  uint64_t seed = 1;  // the bake's seed (its record): the bake's ray streams
  int threads = 0;    // 0 = all cores
};

/// Throws prt::Error unless 1 <= samples <= 16777216 and 0 <= bounces <= 64.
void validate(const BounceSettings& s);

/// The light direct lights send on by interreflection, gathered with rays at relight time
/// instead of through the SH transfer (which would carry a sun's sharp first bounce, the patch
/// it lights through a window, at 3 bands: docs/lights.md, "Their bounces"):
///   E_b = Σ_{k=1}^{B} G^k E⁰,   (G E)(v) = (1/K) Σ_{hits h of v's K rays} ρ(h) E(h),
/// E⁰ the shadowed direct irradiance at every baked vertex (shadowedDirectIrradiance), E(h) its
/// barycentric interpolation at the hit. G is the surface bake's own bounce operator
/// (surface_bake.cpp): the same K cosine-weighted rays per vertex as the bake's first K, the
/// same hit records (front faces, and the back faces of double-sided ones as their back side),
/// the same albedo at the hit. With K the bake's sample count and E⁰ = t⁰ · l for an SH light l,
/// E_b is the bake's (t − t⁰) · l. The rays are traced once, here; bounce() is a gather over the
/// kept hits (8 bytes each), so one DirectBounce relights any number of frames. Which rays
/// escape is kept too (a bit each), for skyDetail().
class DirectBounce {
 public:
  /// Traces K rays from every baked vertex (both sides of double-sided instances) of `scene`,
  /// which must outlive this object.
  DirectBounce(const Scene& scene, const BounceSettings& settings);
  ~DirectBounce();
  DirectBounce(const DirectBounce&) = delete;
  DirectBounce& operator=(const DirectBounce&) = delete;

  /// E_b for direct irradiance `e0` (per instance and side, shadowedDirectIrradiance's layout;
  /// an empty vector counts as zero): the bounced part only, E⁰ not included. Deterministic for
  /// any thread count; `seconds` is the gather's time, `rays` 0.
  DirectIrradiance bounce(const DirectIrradiance& e0) const;

  /// The sky's light beyond the SH band limit at every baked vertex and side ("sky detail",
  /// docs/lights.md):
  ///   Δ(v) = (π/K) Σ_{rays s of v's K that escape} (L(ω_s) − L̃(ω_s)),
  /// L the radiance `sky` (LightRig::shRadiance: what `sh` stands for), L̃ the radiance `sh`
  /// itself (its band-limited reconstruction, window included). t⁰ · sh is ∫ V cos L̃ (the
  /// projections are orthogonal), so t⁰ · sh + Δ estimates the direct sky ∫ V cos L without the
  /// band limit; only the detail L − L̃ is sampled (a control variate), so where it is small the
  /// estimate is as quiet as the SH. The same rays as bounce()'s, in shadowedDirectIrradiance's
  /// layout (empty for instances without transfer). Deterministic for any thread count.
  /// The maps are read averaged down to pixels of about four rays' share of the hemisphere
  /// (2π/K each; two rays across), once per map image and kept for later calls: a bright
  /// feature smaller than that is spread over it, not caught by one ray in a hundred vertices.
  DirectIrradiance skyDetail(const RigBackground& sky, const sh::ShRgb& sh) const;

  uint64_t rays() const;        // traced by the constructor
  uint64_t hitRecords() const;  // kept
  double traceSeconds() const;  // the constructor's time

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace prt::bake
