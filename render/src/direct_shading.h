// Direct lights (suns, small disks) lit per pixel with shadow maps (private header of render/;
// docs/render.md, "Direct lights and their shadows"): the GLSL of the per-pixel term
//   E_direct(x, n) = Σ_k E_k · directCosineFactor_k(n) · visibleShare_k(x)
// (directCosineFactor ported from probes/lights/src/light.cpp, visibleShare from PCSS-filtered
// shadow maps), and the CPU side that fits the shadow maps to the scene and the view.
#pragma once

#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "prt/light.h"
#include "prt/render/renderer.h"

namespace prt::render {

/// Texture unit of the shadow maps (0: base colour, 1–3: probes, 4–11: background maps).
constexpr int kShadowMapUnit = 12;
/// Samples of the blocker search and of the filter (a Vogel spiral turned per pixel).
constexpr int kBlockerSamples = 8, kFilterSamples = 16;
/// Largest search/filter radius, in shadow-map texels: wider penumbrae are sampled this wide.
constexpr int kMaxKernelTexels = 48;

/// GLSL (fragment stage) declaring the direct lights' uniforms, the input vWorldPixel (the
/// world position interpolated at the pixel's centre, which the vertex stage must write),
///   void pixelFootprint(out vec3 dxW, out vec3 dyW)
/// (to call at the top of main: the world position's change across the pixel) and
///   vec3 directIrradiance(vec3 x, vec3 n, vec3 dxW, vec3 dyW)
/// = Σ_k E_k · directCosineFactor_k(n) · visibleShare_k(x) over the pixel's square, the last 1
/// when uShadowed is 0.
std::string directLightingGlsl();

/// One shadow map: an orthographic view along a light, fitted to a box.
struct ShadowLayer {
  glm::dmat4 worldToMap{1.0};  // world -> (x, y in metres from the map's corner, depth in metres from its near plane)
  double side = 1.0;           // metres covered by the square map
  double range = 1.0;          // metres of depth from the near plane to the far plane
  double texel = 1.0;          // side / map size
  double tanRadius = 0.0;      // tan of the light's angular radius (0 for a delta)
  /// Clip coordinates for drawing the map (GL_ZERO_TO_ONE depth: depth / range).
  glm::dmat4 viewProj() const;
};

/// The shadow maps of one frame: lights × cascades layers, light-major.
struct ShadowPlan {
  int cascades = 1;
  glm::dvec4 cascadeFar{1e30};  // view depth where cascade c ends; unused entries 1e30
  glm::dvec3 viewOrigin{0.0}, viewForward{0.0, 0.0, -1.0};
  std::vector<ShadowLayer> layers;
};

/// Fits the maps (docs/render.md): per light, an orthographic box along its direction holding
/// every caster of [lo, hi] in depth; in x and y the part of that box the view sees, split
/// into cascades over view depth when one map's texel would be coarser than two pixels at the
/// nearest visible depth (perspective cameras only). `mapSize` texels a side.
ShadowPlan planShadows(const std::vector<DirectLight>& lights, const CameraView& camera, double aspect, int heightPixels,
                       const glm::dvec3& lo, const glm::dvec3& hi, int mapSize, int maxCascades);

}  // namespace prt::render
