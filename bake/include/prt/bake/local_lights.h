// Lights inside the scene (prt/local_light.h) on a baked scene: which there are at a frame (the
// file's own KHR_lights_punctual lights, moved by its animation, and a rig's), and their exact
// shadowed irradiance at the baked vertices (docs/lights.md, "Lights inside the scene").
#pragma once

#include <vector>

#include "prt/bake/direct_light.h"
#include "prt/bake/ray_scene.h"
#include "prt/light.h"
#include "prt/light_rig.h"
#include "prt/local_light.h"
#include "prt/scene.h"

namespace prt::bake {

/// The frames per second that turn a rig's frame into the scene's animation time when the rig
/// gives none (as `prt render`'s default).
constexpr double kDefaultLightFps = 24.0;

/// The scene's point and spot lights at `time` seconds (their nodes' animation applied), as
/// LocalLights: intensity = colour × intensity (candela), labelled "FILE: light 'NAME'".
std::vector<LocalLight> scenePunctualLightsAt(const Scene& scene, double time);

/// The scene's directional lights at `time` as suns: delta DirectLights towards −(the node's −Z),
/// irradiance colour × intensity (lux read as W/m², as every prt irradiance).
std::vector<DirectLight> sceneSunsAt(const Scene& scene, double time);

/// The scene's emissive surfaces, one Emitter light per non-receiver instance whose material
/// emits, made of its triangles (emissiveFactor × KHR_materials_emissive_strength × the emissive
/// texture's mean over the triangle, 16 stratified texels; the factor alone where the texture
/// was not decoded: LoadOptions::shadingTextures), emitting along its winding's normal, and both
/// ways for a double-sided material. Labelled "FILE: surface 'MESH'". Triangles of zero radiance
/// are left out.
std::vector<LocalLight> emissiveLightsOf(const Scene& scene);

/// The radiance the scene's emissive surfaces emit at their own vertices (emissiveFactor ×
/// strength × the emissive texture at the vertex), per instance: front sides, and back sides
/// of double-sided emitters (`back`); empty vectors for instances that do not emit.
struct VertexEmission {
  std::vector<std::vector<glm::vec3>> front, back;
};
VertexEmission emissionAtVertices(const Scene& scene);

/// Throws prt::Error "RIG: lights[2].node: no node 'Lamp' in SCENE" for a rig light that names a
/// node the scene lacks.
void checkRigNodes(const Scene& scene, const LightRig& rig);

/// The rig's lights inside the scene at `frame`, those on a node placed by the node's world
/// transform at `time` (its rotation and translation; scale moves the position only).
/// Precondition: checkRigNodes.
std::vector<LocalLight> rigLocalLightsAt(const Scene& scene, const LightRig& rig, double frame, double time);

/// Shadowed irradiance of `lights` at every vertex side with transfer (shadowedDirectIrradiance's
/// layout): the unoccluded irradiance in closed form at the vertex (localIrradiance) times the
/// visible share. A point or spot light: one shadow ray. An area light: `settings.samples` rays
/// to points stratified over it (a sphere: directions stratified over the cap it subtends),
/// the share their integrand-weighted mean visibility (a ratio estimator, exact wherever
/// nothing occludes the light). Rays leave from the bake's lifted origins and stop at the light.
/// Deterministic for any thread count.
/// `origins` (if given): the vertex sides' ray origins, as shadowedDirectIrradiance takes them.
DirectIrradiance shadowedLocalIrradiance(const Scene& scene, const RayScene& rays,
                                         const std::vector<LocalLight>& lights, const ShadowSettings& settings = {},
                                         const std::vector<glm::vec3>* origins = nullptr);

/// The same at arbitrary points with their unit normals (`prt probe --scene`): rays leave from
/// each point lifted along its normal by 10⁻⁴ of the scene's extent, as the direct lights'
/// (shadowedDirectIrradianceAt). Deterministic for any thread count.
std::vector<glm::vec3> shadowedLocalIrradianceAt(const RayScene& rays, const std::vector<glm::vec3>& points,
                                                 const std::vector<glm::vec3>& normals,
                                                 const std::vector<LocalLight>& lights,
                                                 const ShadowSettings& settings = {});

}  // namespace prt::bake
