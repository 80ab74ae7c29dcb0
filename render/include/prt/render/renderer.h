// Rendering baked static meshes to linear float images with OpenGL (docs/render.md).
//
// Per vertex (vertex shader): e = transfer · light, the RGB dot product of the vertex's n²
// transfer coefficients with the light's. Per pixel (fragment shader): the interpolated e times
// albedo/π, albedo = baseColorFactor × baseColorTexture(texcoord) × COLOR_0 — the same formula as
// prt::relightVertices, except that albedo is taken per pixel instead of per vertex.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "prt/image.h"
#include "prt/light.h"
#include "prt/light_rig.h"
#include "prt/local_light.h"
#include "prt/probe_grid.h"
#include "prt/render/gl_context.h"
#include "prt/scene.h"
#include "prt/sh.h"

namespace prt::render {

/// Where the picture is taken from. The camera looks down its local -Z with +Y up (glTF).
/// Perspective: `yfov` is the vertical field of view; the horizontal one follows from the
/// image's aspect ratio (a glTF camera's aspectRatio is ignored, so pixels stay square).
/// Orthographic: `ymag` is half the visible height; half the width is ymag × image aspect.
struct CameraView {
  glm::dmat4 cameraToWorld{1.0};  // rotation and translation only
  bool perspective = true;
  double yfov = 0.8;  // radians
  double ymag = 1.0;
  double znear = 0.01;
  double zfar = 0.0;  // 0 = infinite (perspective only)
};

/// The view of a glTF camera of the scene (scale is removed from its world matrix).
CameraView cameraView(const Camera& camera);

/// A camera circling the scene: it sits at target + distance·(cos el sin az, sin el, cos el cos az)
/// and looks at the target with +Y up. Azimuth 0, elevation 0 looks down -Z (glTF's front view).
struct OrbitCamera {
  std::optional<glm::vec3> target;  // default: the centre of the framing box (orbitFraming)
  double distance = 0.0;            // 0 = fit the framing box's sphere into the field of view
  double azimuthDegrees = 0.0;      // about +Y, right-handed
  double elevationDegrees = 20.0;   // clamped to ±89
  double yfovDegrees = 45.0;
};

/// The box a default orbit camera frames: where the geometry is. The per-axis 1st to 99th
/// percentiles of all vertex positions when that box's diagonal is under half the bounds' (a
/// town on a 2 km ground plane, a level with a far skybox), else the scene's bounds.
void orbitFraming(const Scene& scene, glm::dvec3& lo, glm::dvec3& hi);
/// The orbit's target: orbit.target, else the centre of orbitFraming's box.
glm::dvec3 orbitTarget(const Scene& scene, const OrbitCamera& orbit);
/// The view of an orbit camera around `scene` for an image of aspect `aspect` = w / h.
CameraView orbitView(const Scene& scene, const OrbitCamera& orbit, double aspect);

/// What the last frame cost, in milliseconds of wall time (GL work is finished before timing).
struct FrameStats {
  double lightMs = 0.0;     // light update: light uniforms, relightProbes and the probe upload
  double drawMs = 0.0;      // clear, draw, glFinish
  double readbackMs = 0.0;  // glReadPixels and the row flip
  double shadowMs = 0.0;    // the shadow-map pass (part of drawMs)
  size_t triangles = 0;     // drawn in the last frame (baked and receivers)
  size_t receiverTriangles = 0;
  int samples = 1;  // samples per pixel the GL gave (>= Frame::samples; llvmpipe: 4 for 2)
  /// Direct lights of the frame lit per pixel (exactly, with shadow maps), on baked instances
  /// and on receivers; those not lit so went through the SH light (an older bake, a grid
  /// without its direct part).
  size_t directBaked = 0, directReceivers = 0;
  int shadowMaps = 0;       // shadow-map layers drawn (lights × cascades)
  int cascades = 0;         // per light
  int shadowMapSize = 0;    // texels a side
  size_t localLights = 0;   // lights inside the scene lit per pixel (Frame::local)
  int localShadowMaps = 0;  // their cube faces drawn (six per light)
  int localMapSize = 0;     // texels a side of each face
};

/// At most this many direct lights per frame (Frame::direct): each costs a shadow map per
/// cascade and a blocker search per pixel (docs/render.md, "Direct lights and their shadows").
inline constexpr int kMaxDirectLights = 8;
/// At most this many shadow-map cascades per direct light.
inline constexpr int kMaxCascades = 4;
/// At most this many lights inside the scene per frame lit per pixel (Frame::local): each costs
/// six shadow maps and a filter per pixel.
inline constexpr int kMaxLocalLights = 8;

/// How direct lights' shadows are made (docs/render.md).
struct ShadowSettings {
  bool enabled = true;  // false: every visible share is 1 (no shadow maps drawn)
  int mapSize = 1024;   // texels a side of each shadow map, 16..8192
  int maxCascades = 4;  // 1..kMaxCascades; cascades are used only where one map is too coarse
};

/// How a frame is shaded. Flat draws the same instances with the same vertex buffers, depth
/// test and read-back in one constant colour: the raster floor a benchmark compares with.
enum class Shading { Prt, Flat };

/// Where receivers look their probes up. PerPixel (the reference): at every pixel's interpolated
/// position and normal. PerVertex: at the receiver's vertices; the normalised incident radiance
/// Σ w_p c_p / Σ w_p is interpolated across each triangle and the irradiance basis applied at the
/// pixel's normal: cheaper on CPU rasterizers, and equal to PerPixel only as far as the probe
/// field is linear over a triangle (the visibility weights are not: use it for receivers whose
/// triangles are small next to the probe spacing).
enum class ProbeLookup { PerPixel, PerVertex };

/// How surfaces are shaded (docs/render.md, "Materials"). Diffuse: every material Lambertian with
/// its base colour as the albedo (what the transfer alone gives). Full: the glTF
/// metallic-roughness material per pixel: the diffuse albedo baseColor·(1 − metallic), the
/// metallic-roughness, normal, occlusion and emissive textures, the direct lights' GGX
/// highlights and the environment's (Frame::environment) by the split sum.
enum class MaterialShading { Diffuse, Full };

/// At most this many environment maps are reflected (MaterialShading::Full).
inline constexpr int kMaxReflectedMaps = 4;

/// One frame to render.
struct Frame {
  CameraView camera;
  sh::ShRgb light;  // distant light; truncated or zero-padded to the bands in use
  /// Direct lights (docs/render.md, "Direct lights and their shadows"; RigLighting): `light`
  /// is then RigLighting::sh, `directLight` their SH (RigLighting::directSh), which goes only
  /// through the bounced part of the transfer, and `direct` the lights themselves, lit per pixel
  /// with their shadows: E = t·light + (t − t⁰)·directLight + Σ_k E_k c_k(n) s_k(x). Where the
  /// transfer has no direct part (an older bake; a probe grid without one) the direct lights go
  /// through SH instead (light + directLight) and warnings() says so. At most kMaxDirectLights.
  sh::ShRgb directLight;
  std::vector<DirectLight> direct;
  /// The direct lights' bounced irradiance, gathered with rays (prt::bake::DirectBounce), per
  /// Scene::meshes entry and vertex, and for the back sides of two-sided instances: when not
  /// null, baked instances are lit E = t·light + directBounce + Σ_k E_k c_k(n) s_k(x), and
  /// directLight goes only to the receivers. Null: the bounce through (t − t⁰)·directLight.
  /// Must stay alive during render().
  const std::vector<std::vector<glm::vec3>>* directBounce = nullptr;
  const std::vector<std::vector<glm::vec3>>* directBounceBack = nullptr;
  /// Lights inside the scene lit per pixel with their shadows (point, spot, sphere, disk and
  /// rectangle lights; other types are skipped: an emissive surface's light comes in
  /// directBounce), each from a cube of shadow maps about its centre (docs/render.md, "Lights
  /// inside the scene"). At most kMaxLocalLights. Only where the baked instances are lit per
  /// pixel (a bake with the direct part of its transfer) and on receivers whose grid has it.
  std::vector<LocalLight> local;
  /// Added to the relit probes of the grid (setProbes; relightProbes' layout): the bounced light
  /// the bake's operator brings each probe (prt::bake::addProbeBounce; docs/lights.md, "Probes
  /// through the operator"). Only where the receivers split the direct lights off. Null: none.
  /// Must stay alive during render().
  const std::vector<glm::vec3>* probeBounce = nullptr;
  ShadowSettings shadows;
  double time = 0.0;  // seconds: receivers are placed by the scene's animations at time
  int width = 0;      // 0: the context's size
  int height = 0;
  Shading shading = Shading::Prt;
  ProbeLookup probeLookup = ProbeLookup::PerPixel;
  /// What pixels that no instance covers show: null = 0 (black); else the lights' radiance
  /// seen along each pixel's centre ray (RigBackground::radiance, LightRig::background). At
  /// most kMaxBackgroundMaps environment maps and kMaxBackgroundCaps suns and disks.
  const RigBackground* background = nullptr;
  MaterialShading materials = MaterialShading::Diffuse;
  /// The light glossy surfaces reflect besides the direct lights (MaterialShading::Full): the
  /// rig's SH part (LightRig::shRadiance: the maps' residuals where suns were split off, the
  /// uniform lights). Its caps (disks wider than the direct lights) are not reflected. Null: no
  /// environment reflection. At most kMaxReflectedMaps maps; must stay alive during render().
  const RigBackground* environment = nullptr;
  /// Multisample anti-aliasing: samples per pixel, 1 (off) or a power of two up to the GL's
  /// GL_MAX_SAMPLES (4 on llvmpipe). Each pixel is shaded once (at its centre, or at the
  /// centroid of its covered samples on an edge) and the written pixel is the mean of its
  /// samples: pixels that one surface covers entirely are unchanged.
  int samples = 1;
  /// Screen-space reflections (MaterialShading::Full, samples 1; docs/render.md, "Materials"):
  /// where the room hides part of a glossy lobe, that share reflects the surface the mirror
  /// direction meets on the screen, found through the depth buffer, instead of the surroundings'
  /// mean radiance; where it meets none there, the mean stays.
  bool screenReflections = true;

  /// Takes a rig's light of the frame: `light`, `directLight` and `direct` from `rig` (moved),
  /// and the gathered vertex light (`directBounce`, `directBounceBack`; null for none).
  void setLight(RigLighting&& rig, const std::vector<std::vector<glm::vec3>>* bounce = nullptr,
                const std::vector<std::vector<glm::vec3>>* bounceBack = nullptr) {
    light = std::move(rig.sh);
    directLight = std::move(rig.directSh);
    direct = std::move(rig.direct);
    directBounce = bounce;
    directBounceBack = bounceBack;
  }
};

inline constexpr int kMaxBackgroundMaps = 8;
inline constexpr int kMaxBackgroundCaps = 64;
/// Throws prt::Error "WHAT: N environment maps, at most 8 can be drawn" (or the suns and disks'
/// limit) when a background has more than the renderer draws.
void checkBackgroundSize(const std::string& what, size_t maps, size_t caps);

/// The scene uploaded to one GlContext; renders frames of it under any SH light. Baked instances
/// are lit by their transfer; receivers (MeshInstance::receiverOnly) from the probe grid given to
/// setProbes(), and are not drawn without one (see warnings()). Unbaked instances that are not
/// receivers are skipped with a warning. The context must outlive the renderer.
class Renderer {
 public:
  /// Uploads geometry, transfer and textures. Throws prt::Error if the scene has neither a
  /// baked instance nor a receiver, or the GL cannot hold it (e.g. a transfer buffer larger than
  /// the GL allows).
  Renderer(GlContext& context, const Scene& scene);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Lights the receivers from `grid` from the next frame on: its static data (probe positions,
  /// validity, distance moments) is uploaded now, its incident radiance c_p = M_p · l is
  /// recomputed (relightProbes) and uploaded every frame. `grid` must stay alive and unchanged
  /// while the renderer uses it (until the renderer or the next setProbes). Throws prt::Error if
  /// the GL cannot hold the grid.
  void setProbes(const ProbeGrid& grid);

  /// Renders a frame of exitant radiance (background 0 unless Frame::background), row 0 at the
  /// top. Makes the context current.
  ImageRgb render(const Frame& frame);
  /// A frame at time 0, width × height.
  ImageRgb render(const CameraView& camera, const sh::ShRgb& light, int width, int height);
  /// A frame at time 0 at the context's frame size.
  ImageRgb render(const CameraView& camera, const sh::ShRgb& light);

  /// Bands of the baked transfer (0 if the scene has only receivers).
  int bands() const;
  /// Number of receiver instances (drawn once setProbes was called).
  size_t receiverCount() const;
  const FrameStats& lastFrame() const;
  /// Whether the baked instances hold the transfer's direct part (direct lights lit exactly).
  bool bakedDirectPart() const;
  /// One line per skipped instance ("skipping unbaked instance 'x': ..."), one line naming
  /// the receivers while no probe grid is set (they are not drawn then), and, once a frame
  /// had direct lights, one line for each part that lit them through SH instead (an older
  /// bake, a probe grid without its direct part).
  std::vector<std::string> warnings() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace prt::render
