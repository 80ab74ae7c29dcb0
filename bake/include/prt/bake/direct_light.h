// The exact light of direct lights (suns, small disks) at baked vertices: their unoccluded
// irradiance over the cap (clipped by the horizon) times the share of it that shadow rays find
// unblocked. With the transfer's direct part this replaces the band-limited sun
// (docs/lights.md, "Direct lights").
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "prt/light.h"
#include "prt/scene.h"

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

/// Shadowed irradiance of `lights` at every vertex of every instance that holds transfer (the
/// baked ones), traced against the scene's non-receiver instances from the origins the bake's
/// rays leave from (lifted off the surface as in the bake). Visible share: the cosine-weighted
/// mean visibility of `samples` directions stratified uniformly over the cap (Sobol, scrambled
/// per vertex and light), a ratio estimator that is exact wherever nothing occludes the cap.
/// Deterministic for any thread count.
DirectIrradiance shadowedDirectIrradiance(const Scene& scene, const std::vector<DirectLight>& lights,
                                          const ShadowSettings& settings = {});

}  // namespace prt::bake
