// Direct lights per pixel with PCSS-filtered shadow maps (docs/render.md, "Direct lights and
// their shadows").
//
// For a direct light k (a cap of angular radius r around d, irradiance E_k on a surface facing
// it) a pixel at x with unit normal n receives
//   E_k · directCosineFactor_k(n) · visibleShare_k(x)
// directCosineFactor is light.cpp's closed form (Note 4 there) in float; visibleShare is read
// from an orthographic shadow map along d:
// 1. The map stores, per texel, the depth (metres along −d from the map's near plane) of the
//    nearest caster. A receiver at map position p (metres) and depth z is occluded along the
//    light's centre direction where the stored depth is smaller.
// 2. Blocker search (PCSS, Fernando 2005): any occluder of the cap lies between the near plane
//    and x, so within a disk of radius tan r · z around p. kBlockerSamples points of a Vogel
//    spiral over that disk find the blockers and their mean depth z_b. None: fully lit (1).
// 3. Filter: a ray from x towards d + δ (|δ| ≤ tan r, the cap seen in the tangent plane) meets
//    the blocker plane at lateral offset (z − z_b) δ, so the share of the cap that arrives is the
//    share of the disk of radius tan r · (z − z_b) whose map depth lies beyond the receiver:
//    kFilterSamples spiral points, each compared. Exact for a planar occluder parallel to the
//    map (the cap taken uniform over the disk, ignoring the cosine's variation across a cap of
//    at most 20°), the usual PCSS approximation otherwise. Every blocker-search sample blocked
//    (and the filter disk inside the searched one): fully shadowed (0).
// Comparisons are against the receiver's tangent plane, not its centre depth ("receiver plane
// depth bias", Isidoro 2006): at offset o the receiver lies at z + grad · o, grad = n_xy / |n_z|
// in light space (|n_z| floored at 0.02, 88.9°), less a bias of (1 + |grad|) texels for the nearest-texel
// quantisation. The spiral is turned per pixel by interleaved gradient noise (Jimenez 2014) of
// the pixel position: deterministic, and it turns the banding of a few samples into noise.
// 4. Over the pixel's square: a pixel is the mean over its square, so both disks are convolved
//    with the square mapped into the map (pixelFootprint): each sample adds an R2 point of the
//    square to its spiral point. A pixel across an edge sharper than a pixel gets its square's
//    share, not the 0 or 1 at its centre.
// 5. Samples on empty texels (nothing drawn there) lie on no surface and do not vote: every
//    sample on a surface blocked is fully shadowed, the filter's share is over those samples.
//
// Loops. llvmpipe (Mesa 22.3) runs a fragment shader on vectors of pixels and executes both sides
// of every branch for all of them (masked), but it leaves a loop once no pixel of the vector
// needs another pass (the test is at the loop's end: the body always runs once). So work that
// most pixels skip goes into a loop, not an if: the blocker search (skipped where the cap is
// below the horizon), the filter (most pixels need none) and the lights (one light costs one
// pass, not two). The loops step by the uniform uLoopStep (1): with a
// constant step Mesa's NIR can bound the trip count and unroll the loop into straight code,
// which llvmpipe then runs whole for every pixel (measured, docs/render.md "Cost").
#include "direct_shading.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "prt/error.h"
#include "render_shaders.h"
#include "shader_sources.h"

namespace prt::render {

std::string directLightingGlsl() {
  return fillShader(shaders::kDirectLighting, {{"MAX_DIRECT", cat(kMaxDirectLights)},
                                               {"MAX_SHADOW_LAYERS", cat(kMaxDirectLights * kMaxCascades)},
                                               {"SHADOW_UNIT", cat(kShadowMapUnit)},
                                               {"BLOCKER_SAMPLES", cat(kBlockerSamples)},
                                               {"FILTER_SAMPLES", cat(kFilterSamples)},
                                               {"MAX_KERNEL", cat(kMaxKernelTexels)}});
}

glm::dmat4 ShadowLayer::viewProj() const {
  glm::dmat4 s(1.0);
  s[0][0] = 2.0 / side;
  s[1][1] = 2.0 / side;
  s[3][0] = -1.0;
  s[3][1] = -1.0;
  s[2][2] = 1.0 / range;
  return s * worldToMap;
}

ShadowPlan planShadows(const std::vector<DirectLight>& lights, const CameraView& camera, double aspect,
                       int heightPixels, const glm::dvec3& lo, const glm::dvec3& hi, int mapSize, int maxCascades) {
  PRT_CHECK(mapSize >= 1);
  ShadowPlan plan;
  plan.viewOrigin = glm::dvec3(camera.cameraToWorld[3]);
  plan.viewForward = -glm::normalize(glm::dvec3(camera.cameraToWorld[2]));
  const glm::dvec3 right = glm::normalize(glm::dvec3(camera.cameraToWorld[0]));
  const glm::dvec3 up = glm::normalize(glm::dvec3(camera.cameraToWorld[1]));
  std::array<glm::dvec3, 8> box;
  for (int i = 0; i < 8; ++i) box[size_t(i)] = glm::dvec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
  const double diag = std::max(glm::length(hi - lo), 1e-6);

  // View depths the casters' box spans, and the cascades.
  double dNear = 1e300, dFar = -1e300;
  for (const glm::dvec3& c : box) {
    const double d = glm::dot(c - plan.viewOrigin, plan.viewForward);
    dNear = std::min(dNear, d);
    dFar = std::max(dFar, d);
  }
  // The nearest depth that matters: the box's, but at least a quarter of the farthest (a camera
  // inside the box would otherwise ask for texels as fine as its near plane; what lies closer
  // than a quarter of the view's depth gets the first cascade's texels).
  const double farthest = std::max(dFar, camera.znear * 1.001 + 1e-9);
  const double nearest = std::clamp(std::max(dNear, 0.25 * farthest), camera.znear, farthest / 1.001);
  const double tanY = std::tan(0.5 * camera.yfov);
  std::vector<double> splits = {nearest, farthest};
  if (camera.perspective && maxCascades > 1) {
    // One map over the whole box has texels of at most diag / mapSize; a pixel at depth z covers
    // z · 2 tan(fov/2) / height. Cascades only where that texel exceeds two pixels at the
    // nearest visible depth; each then covers a depth ratio of about 3 (practical split scheme,
    // Zhang et al. 2006: λ = 0.75 of logarithmic, the rest uniform).
    const double pixel = nearest * 2.0 * tanY / std::max(heightPixels, 1);
    if (diag / mapSize > 2.0 * pixel) {
      const int n = std::clamp(int(std::ceil(std::log(farthest / nearest) / std::log(3.0))), 1, maxCascades);
      splits.assign(size_t(n) + 1, 0.0);
      for (int i = 0; i <= n; ++i) {
        const double f = double(i) / n;
        splits[size_t(i)] = 0.75 * nearest * std::pow(farthest / nearest, f) + 0.25 * (nearest + (farthest - nearest) * f);
      }
    }
  }
  plan.cascades = int(splits.size()) - 1;
  plan.cascadeFar = glm::dvec4(1e30);
  for (int c = 0; c + 1 < plan.cascades && c < 4; ++c) plan.cascadeFar[c] = splits[size_t(c) + 1];

  for (const DirectLight& light : lights) {
    // Light space: e3 = −d (depth grows away from the light), e1, e2 across.
    const glm::dvec3 e3 = -glm::normalize(light.direction);
    const glm::dvec3 helper = std::abs(e3.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
    const glm::dvec3 e1 = glm::normalize(glm::cross(helper, e3)), e2 = glm::cross(e3, e1);
    glm::dvec3 bLo(1e300), bHi(-1e300);
    for (const glm::dvec3& c : box) {
      const glm::dvec3 l(glm::dot(c, e1), glm::dot(c, e2), glm::dot(c, e3));
      bLo = glm::min(bLo, l);
      bHi = glm::max(bHi, l);
    }
    const double eps = 1e-3 * diag;
    bLo.z -= eps;
    bHi.z += eps;
    const double range = bHi.z - bLo.z;
    const double tanR = light.radius < kPointSunRadians ? 0.0 : std::tan(light.radius);
    for (int c = 0; c < plan.cascades; ++c) {
      // The slice of the view between splits[c] and splits[c + 1], in light space.
      glm::dvec2 sLo(1e300), sHi(-1e300);
      for (int k = 0; k < 8; ++k) {
        // The first slice starts at the near plane: what lies closer than `nearest` is in it too.
        const double z = c == 0 && !(k & 1) ? std::min(camera.znear, splits[0]) : splits[size_t(c) + (k & 1)];
        const double hh = camera.perspective ? z * tanY : camera.ymag, hw = hh * aspect;
        const glm::dvec3 p = plan.viewOrigin + plan.viewForward * z + right * (k & 2 ? hw : -hw) + up * (k & 4 ? hh : -hh);
        const glm::dvec2 l(glm::dot(p, e1), glm::dot(p, e2));
        sLo = glm::min(sLo, l);
        sHi = glm::max(sHi, l);
      }
      glm::dvec2 xLo = glm::max(sLo, glm::dvec2(bLo)), xHi = glm::min(sHi, glm::dvec2(bHi));
      xHi = glm::max(xHi, xLo + 1e-6 * diag);
      double side = std::max(xHi.x - xLo.x, xHi.y - xLo.y);
      // A margin for the search and filter disks of receivers at the edge of the slice, and two
      // texels for the snapping below.
      const double grow = std::min(tanR * range, 0.25 * side) + 4.0 * side / mapSize;
      side += 2.0 * grow + 2.0 * side / mapSize;
      // Texel snapping (stable cascades, Valient 2008): the side is rounded up to a step of a
      // ladder fixed by the casters' box (diag · 2^(k/8)) and the map's corner down to a whole
      // texel of light space, so the texel grid stays put in the world while the camera moves
      // and jumps only when the side crosses a step (texels at most 9% coarser): shadow edges
      // do not crawl from frame to frame. The corner moves by less than a texel, which the
      // texels added above cover.
      side = diag * std::exp2(std::ceil(8.0 * std::log2(side / diag) - 1e-9) / 8.0);
      const double texel = side / mapSize;
      const glm::dvec2 centre = 0.5 * (xLo + xHi), corner = glm::floor((centre - 0.5 * side) / texel) * texel;
      ShadowLayer layer;
      layer.side = side;
      layer.range = range;
      layer.texel = texel;
      layer.tanRadius = tanR;
      const glm::dvec3 axes[3] = {e1, e2, e3};
      const double offset[3] = {corner.x, corner.y, bLo.z};
      layer.worldToMap = glm::dmat4(1.0);
      for (int r = 0; r < 3; ++r) {
        for (int col = 0; col < 3; ++col) layer.worldToMap[col][r] = axes[r][col];
        layer.worldToMap[3][r] = -offset[r];
      }
      plan.layers.push_back(layer);
    }
  }
  return plan;
}

}  // namespace prt::render
