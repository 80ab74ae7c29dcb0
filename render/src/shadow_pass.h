// The shadow maps of the direct lights (private header of render/; docs/render.md, "Direct
// lights and their shadows"): how the maps are fitted to the casters and the view. The pass that
// draws them is Renderer::Impl::drawShadows (shadow_pass.cpp); the shaders that read them are in
// direct_shading.h.
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "prt/light.h"
#include "prt/render/renderer.h"

namespace prt::render {

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
ShadowPlan planShadows(const std::vector<DirectLight>& lights, const CameraView& camera, double aspect,
                       int heightPixels, const glm::dvec3& lo, const glm::dvec3& hi, int mapSize, int maxCascades);

}  // namespace prt::render
