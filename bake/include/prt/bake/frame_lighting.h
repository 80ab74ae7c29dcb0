// The light of a frame on a baked scene, as `prt render` and `prt relight` light it
// (docs/lights.md): the rig's SH light with its direct lights (suns, small disks) apart, and what
// the bake's own rays gather at the baked vertices, traced once per object: the direct lights'
// bounces ("Their bounces") and the sky's light beyond the SH band limit ("Sky detail"). A frame
// whose direct lights and sky are those of the frame gathered last reuses that gather.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/direct_light.h"
#include "prt/bake/ray_scene.h"
#include "prt/light_rig.h"
#include "prt/local_light.h"
#include "prt/scene.h"

namespace prt::bake {

struct FrameLightingSettings {
  /// False: every light through the SH transfer (no direct light apart, nothing gathered).
  bool directLights = true;
  /// Rays per baked vertex (the bake's first ones) that gather the direct lights' bounces and
  /// the sky detail; 0: both through the SH transfer.
  int gatherSamples = 256;
  /// False: the sky through the SH transfer alone, without its light beyond the band limit.
  bool skyDetail = true;
  /// True: where the bake stored its bounce operator (prt/bounce_operator.h), the bounces and the
  /// sky detail go through it (nothing traced at start-up, sparse products per light change).
  /// False, or a bake without one: the bake's rays are traced again and gathered.
  bool useOperator = true;
  /// True: the direct lights' shadowed light is part of FrameLight::vertexLight (a relit
  /// .glb). False: it is lit elsewhere (per pixel, by the renderer), and only what it sends on
  /// is gathered here.
  bool directAtVertices = false;
  /// Shadow rays per direct light and vertex for the light at the vertices, or for the light
  /// whose bounces are gathered.
  int shadowSamples = 64;
  /// True: the scene's own KHR_lights_punctual lights and emissive surfaces light it too (point
  /// and spot lights and emissive triangles as lights inside the scene, directional lights as
  /// suns; docs/lights.md, "Lights inside the scene"). A rig's lights inside the scene light it
  /// either way.
  bool sceneLights = false;
  /// True: the renderer lights the lights inside the scene that it can (localLightPerPixel)
  /// per pixel with their shadow maps, so their shadowed light is left out of
  /// FrameLight::vertexLight and only their bounces are in it; emissive surfaces stay there.
  bool localPerPixel = false;
  /// Shadow rays per area light (or emissive surface) and vertex for the lights inside the
  /// scene lit at the vertices; 0: shadowSamples. With localPerPixel, the lights the renderer
  /// lights take shadowSamples (their E⁰ at the vertices only bounces).
  int localShadowSamples = 0;
  /// False: the caller reads the frame's lights and, where the bounces are gathered, their
  /// operator values (`prt probe`), never FrameLight::vertexLight: nothing is lit at the
  /// vertices unless the bounces need it.
  bool vertexLight = true;
  int threads = 0;  // 0 = all cores
};

/// Whether the renderer lights `light` per pixel (FrameLightingSettings::localPerPixel): point,
/// spot, sphere, disk and rectangle lights; an emissive surface's triangles stay at the vertices.
inline bool localLightPerPixel(const LocalLight& light) {
  return light.type != LocalLight::Type::Triangle && light.type != LocalLight::Type::Emitter;
}

struct FrameLight {
  /// The rig at the frame on the scene's bands: `sh` lit through the transfer, `direct` apart.
  /// With directAtVertices and the bounces gathered, `directSh` is zero (nothing of the direct
  /// lights goes through the transfer); in a bake without the direct part (an older prt's) the
  /// direct lights are moved into `sh` (foldedLights).
  RigLighting rig;
  /// Per instance and side (DirectIrradiance's layout), irradiance added at the baked vertices;
  /// null when nothing is. directAtVertices: E⁰ + Δ + E_b (the direct lights' shadowed light, the
  /// sky detail, their bounces); else E_b + Δ. Valid until the next at().
  const DirectIrradiance* vertexLight = nullptr;
  /// The lights inside the scene at this frame (the scene's, then the rig's): their bounces are
  /// in vertexLight, and their shadowed light too unless the renderer lights them per pixel
  /// (localPerPixel).
  std::vector<LocalLight> local;
  /// How many of rig.direct are the scene's directional lights (the last ones).
  size_t sceneSuns = 0;
  size_t foldedLights = 0;
  /// Where the bounces go through the bake's operator and it has probe rows: its node values of
  /// the last light change (OperatorLighting::nodeValues), for those rows (addProbeBounce);
  /// else null.
  /// Valid until the next at().
  const std::vector<glm::vec3>* operatorValues = nullptr;
  bool updated = false;  // vertexLight was gathered for this frame (not reused)
  double seconds = 0.0;  // this frame's light: the rig, shadow rays and gather (not the trace)
};

struct FrameLightingStats {
  uint64_t gatherRays = 0;  // traced once, from every baked vertex (0 through the operator)
  double traceSeconds = 0.0;
  int updates = 0;                                                       // frames whose vertex light was gathered
  uint64_t shadowRays = 0;                                               // over all updates
  double updateSeconds = 0.0, shadowSeconds = 0.0, gatherSeconds = 0.0;  // over all updates
  // Through the operator, gatherSeconds by part (OperatorTimes): the sky bins, the products at
  // the clusters, the products at the vertex sides.
  double skySeconds = 0.0, clusterSeconds = 0.0, vertexSeconds = 0.0;
};

/// The light of each frame of a rig on a baked scene. Which gathers it makes is decided at the
/// first at() (the set of direct lights is the same in every frame: their types and radii
/// decide); the bake's rays are traced then.
class FrameLighting {
 public:
  /// `scene` (baked) and `rig` (prepared for the scene's bands, or not) must outlive this.
  /// Throws prt::Error for a rig light on a node the scene lacks (checkRigNodes).
  FrameLighting(const Scene& scene, const LightRig& rig, const FrameLightingSettings& settings);
  ~FrameLighting();
  FrameLighting(const FrameLighting&) = delete;
  FrameLighting& operator=(const FrameLighting&) = delete;

  /// The light at `frame`.
  FrameLight at(double frame);

  /// Whether the bake's rays gather (a bounce or the sky detail), and whether the sky detail is
  /// among it; false until the first at().
  bool gathers() const;
  bool skyDetail() const;
  /// Whether that goes through the bake's bounce operator (else through rays traced again).
  bool usesOperator() const;
  const FrameLightingStats& stats() const;
  /// The static scene's rays where at() built them (for its shadow rays), else null: a caller
  /// that traces more at the same scene shares them (PointShadows).
  const RayScene* rays() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The rig's lighting at `frame` on `bands` bands with its direct lights apart
/// (LightRig::evaluateLighting), or with `directLights` false everything in `sh`.
RigLighting rigLighting(const LightRig& rig, double frame, int bands, bool directLights);

/// Direct lights' and lights inside the scene's shadowed irradiance at arbitrary points of a baked
/// scene whose rays are built once (shadowedDirectIrradianceAt, shadowedLocalIrradianceAt), for
/// a command that asks many times.
class PointShadows {
 public:
  explicit PointShadows(const Scene& scene) : own_(std::in_place, scene), rays_(*own_) {}
  /// Tracing `rays` (built from the scene, e.g. FrameLighting::rays()), which must outlive this.
  explicit PointShadows(const RayScene& rays) : rays_(rays) {}
  PointShadows(const PointShadows&) = delete;
  PointShadows& operator=(const PointShadows&) = delete;
  std::vector<glm::vec3> irradiance(const std::vector<glm::vec3>& points, const std::vector<glm::vec3>& normals,
                                    const std::vector<DirectLight>& lights, const ShadowSettings& settings) const;
  /// The same for lights inside the scene (shadowedLocalIrradianceAt).
  std::vector<glm::vec3> irradiance(const std::vector<glm::vec3>& points, const std::vector<glm::vec3>& normals,
                                    const std::vector<LocalLight>& lights, const ShadowSettings& settings) const;

 private:
  std::optional<RayScene> own_;
  const RayScene& rays_;
};

}  // namespace prt::bake
