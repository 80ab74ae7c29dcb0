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
#include <cstdio>

#include "prt/error.h"
#include "prt/math.h"

namespace prt::render {

namespace {

std::string glslFloat(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9e", v);
  return buf;
}

// Vogel spiral: point i of n at radius √((i + ½)/n), angle i · golden angle: even density over
// the unit disk for any n. The loops below walk it, turning by kGolden from one point to the next.
std::string goldenGlsl() {
  const double a = 2.399963229728653;
  // R2 (Roberts 2018): the additive recurrence of the plastic number, even in the unit square.
  const double g = 1.32471795724474602596;
  return cat("const vec2 kR2 = vec2(", glslFloat(1.0 / g), ", ", glslFloat(1.0 / (g * g)), ");\n",
             "const mat2 kGolden = mat2(", glslFloat(std::cos(a)), ", ", glslFloat(std::sin(a)), ", ",
             glslFloat(-std::sin(a)), ", ", glslFloat(std::cos(a)), ");\n");
}

constexpr const char* kDirectHeadGlsl = R"(
in vec3 vWorldPixel;                         // vWorld, interpolated at the pixel's centre
uniform int uDirectCount;
uniform vec4 uDirectDir[kMaxDirect];         // unit direction towards the light, sin² r (0: a delta)
uniform vec4 uDirectIrradiance[kMaxDirect];  // RGB irradiance on a surface facing it, cot r
uniform int uShadowed;                       // 0: every visible share is 1
uniform int uLoopStep;                       // 1; see "Loops" below
uniform int uCascades;
uniform vec4 uCascadeFar;                    // view depth where cascade c ends
uniform vec3 uViewOrigin;
uniform vec3 uViewForward;
uniform int uShadowSize;                     // texels a side
uniform mat4 uShadowMatrix[kMaxShadowLayers];  // world -> map metres (x, y) and depth (z)
uniform vec4 uShadowParams[kMaxShadowLayers];  // texel (m), depth range (m), tan r, 0
layout(binding = kShadowUnit) uniform sampler2DArray uShadowMap;

// atan(y, x) to float precision (Cephes' atanf, as the background shader's atan2Accurate):
// GLSL's atan and acos are polynomial approximations, off by ~1e-4 rad on Mesa.
float atan2Direct(float y, float x) {
  float ax = abs(x), ay = abs(y);
  float t = min(ax, ay) / max(max(ax, ay), 1e-30);
  bool reduce = t > 0.41421356;
  float r = reduce ? (t - 1.0) / (t + 1.0) : t;
  float z = r * r;
  float a = (((8.05374449538e-2 * z - 1.38776856032e-1) * z + 1.99777106478e-1) * z - 3.33329491539e-1) * z * r + r;
  a += reduce ? 0.78539816339 : 0.0;
  a = ay > ax ? 1.57079632679 - a : a;
  a = x < 0.0 ? 3.14159265358979 - a : a;
  return y < 0.0 ? -a : a;
}

// BEGIN directCosineFactor port (probes/lights/src/light.cpp, Note 4), step for step.
float directCosineFactor(vec3 n, vec4 dirSin2, float cotR) {
  float c = clamp(dot(n, dirSin2.xyz), -1.0, 1.0);
  float sin2 = dirSin2.w;
  if (sin2 <= 0.0 || c * c > sin2) return max(c, 0.0);  // a delta, or wholly above (below) the horizon
  float s = sqrt(max(0.0, 1.0 - c * c));
  float x = cotR;
  float y = clamp(-x * c / max(s, 1e-30), -1.0, 1.0);
  float sq = sqrt(max(0.0, 1.0 - y * y));
  float sy = s * sq;
  float e = (c * atan2Direct(sq, y) - x * sy) * sin2 + atan2Direct(sy, x);  // acos y = atan2(√(1 − y²), y)
  return clamp(e / (3.14159265358979 * sin2), 0.0, 1.0);
}
// END directCosineFactor port.

// Caster depth (in units of the map's depth range) at map position t (texels), nearest texel;
// beyond the map: none. Through textureLod with nearest filtering at the texel's centre, not
// texelFetch: the same texel, and 15% fewer instructions a frame on llvmpipe (Mesa 22.3; measured,
// docs/render.md "Cost"). inv: 1 / uShadowSize.
float mapDepth(int layer, vec2 t, float inv) {
  vec2 i = floor(t);
  bool inside = all(greaterThanEqual(i, vec2(0.0))) && all(lessThan(i, vec2(float(uShadowSize))));
  float d = textureLod(uShadowMap, vec3((i + 0.5) * inv, float(layer)), 0.0).r;
  return inside ? d : 1e30;
}

// The world position's change across one pixel in x and in y, called at the top of main (in
// uniform control flow, before any discard): the quad's differences of vWorldPixel, vWorld
// interpolated at the pixel's centre (vWorld itself is centroid: with multisampling the quad's
// centroids would skew the differences). Measured on llvmpipe, these are the secants between
// pixel centres; interpolateAtOffset there is not perspective-correct (18% too wide on a floor
// seen at a grazing angle). With multisampling a fragment covers only its samples of the pixel
// and is shaded at their centroid: its square shrinks with the share of the samples it covers
// (measured on the validation room, whose floor triangles are smaller than its pixels, --msaa 4
// against a box-filtered Cycles frame: 7.8% pixel RMS shrunk so, 8.2% shrunk to the share's
// area, 8.8% a whole pixel, 7.8% no footprint).
void pixelFootprint(out vec3 dxW, out vec3 dyW) {
  float share = float(bitCount(gl_SampleMaskIn[0])) / float(max(gl_NumSamples, 1));
  dxW = share * dFdx(vWorldPixel);
  dyW = share * dFdy(vWorldPixel);
}

// The share of light k's cap seen from x (normal n) over the pixel's footprint. `facing`: the cap
// is above the horizon; where it is not the result is unused, and the loops stop after one pass.
// dxW, dyW: the world position's change across one pixel (pixelFootprint).
float visibleShare(int k, vec3 x, vec3 n, bool facing, vec3 dxW, vec3 dyW) {
  float depth = dot(x - uViewOrigin, uViewForward);
  int c = min(int(depth > uCascadeFar.x) + int(depth > uCascadeFar.y) + int(depth > uCascadeFar.z), uCascades - 1);
  int layer = k * uCascades + c;
  vec4 P = uShadowParams[layer];
  float texel = P.x, range = P.y, tanR = P.z;
  vec3 p = (uShadowMatrix[layer] * vec4(x, 1.0)).xyz;
  mat3 m3 = mat3(uShadowMatrix[layer]);
  vec3 nl = m3 * n;
  float nz = nl.z < 0.0 ? min(nl.z, -0.02) : max(nl.z, 0.02);
  vec2 grad = -nl.xy / nz;  // the tangent plane's depth slope (|n_z| floored: 88.9°)
  float slope = length(grad);
  // Across in texels, along in units of the depth range: no division per sample.
  vec2 pt = p.xy / texel;
  float inv = 1.0 / float(uShadowSize);
  vec2 gradT = grad * (texel / range);
  float zr = (p.z - texel * (1.0 + slope)) / range;
  // The footprint: the pixel's square [-1/2, 1/2]^2 mapped into the map (J, texels) and the
  // depth along it (Jz, exact on the triangle's plane), at most kMaxKernel texels across.
  vec3 fx = m3 * dxW, fy = m3 * dyW;
  mat2 J = mat2(fx.xy, fy.xy) / texel;
  vec2 Jz = vec2(fx.z, fy.z) / range;
  float fs = min(1.0, kMaxKernel / max(max(length(J[0]), length(J[1])), 1e-30));
  J *= fs;
  Jz *= fs;
  float noise = fract(52.9829189 * fract(dot(gl_FragCoord.xy, vec2(0.06711056, 0.00583715))));
  float ang = 6.28318530718 * noise;
  vec2 turn = vec2(cos(ang), sin(ang));
  vec2 u0 = vec2(noise, fract(noise + 0.5));  // the footprint's points: R2 from u0, less 1/2
  float search = clamp(tanR * p.z / texel, 1.5, kMaxKernel);
  // 1. Blocker search over the search disk convolved with the footprint. A sample on an empty
  //    texel (nothing drawn: depth 1, or beyond the map) lies on no surface, so it does not
  //    vote: there the receiver's tangent plane runs on past the receiver's end (under the wall
  //    a floor meets), and counting it lit would leak light along every contact line.
  float nb = 0.0, ns = 0.0, sumB = 0.0;
  int i = 0;
  vec2 dir = turn * search, u = u0;
  do {
    vec2 o = dir * sqrt((float(i) + 0.5) / float(kBlockerSamples)), box = u - 0.5;
    float zb = mapDepth(layer, pt + o + J * box, inv);
    bool b = zb < zr + dot(gradT, o) + dot(Jz, box);
    nb += b ? 1.0 : 0.0;
    ns += zb < 1.0 ? 1.0 : 0.0;
    sumB += b ? zb : 0.0;
    dir = kGolden * dir;
    u = fract(u + kR2);
    i += uLoopStep;
  } while (facing && i < kBlockerSamples);
  // 2. The penumbra's radius (texels).
  float pen = clamp(tanR * (p.z - range * sumB / max(nb, 1.0)) / texel, 1.0, kMaxKernel);
  bool needFilter = nb > 0.0 && !(nb == ns && pen <= search);
  // 3. The filter over the penumbra's disk convolved with the footprint, over the samples on a
  //    surface: pixels that need none pay one pass of it.
  float lit = 0.0, nf = 0.0;
  i = 0;
  dir = turn * pen;
  u = u0;
  do {
    vec2 o = dir * sqrt((float(i) + 0.5) / float(kFilterSamples)), box = u - 0.5;
    float zf = mapDepth(layer, pt + o + J * box, inv);
    bool surface = zf < 1.0;
    lit += surface && zf >= zr + dot(gradT, o) + dot(Jz, box) ? 1.0 : 0.0;
    nf += surface ? 1.0 : 0.0;
    dir = kGolden * dir;
    u = fract(u + kR2);
    i += uLoopStep;
  } while (facing && needFilter && i < kFilterSamples);
  return needFilter ? (nf > 0.0 ? lit / nf : 1.0) : nb == 0.0 ? 1.0 : 0.0;
}

// Σ_k E_k · directCosineFactor_k(n) · visibleShare_k(x), a loop over the lights that tests at
// its end, so that one light costs one pass.
vec3 directIrradiance(vec3 x, vec3 n, vec3 dxW, vec3 dyW) {
  vec3 e = vec3(0.0);
  int k = 0;
  do {
    float f = directCosineFactor(n, uDirectDir[k], uDirectIrradiance[k].w);
    float v = 1.0;
    if (uShadowed != 0) v = visibleShare(k, x, n, f > 0.0, dxW, dyW);
    e += k < uDirectCount ? uDirectIrradiance[k].rgb * (f * v) : vec3(0.0);
    k += uLoopStep;
  } while (k < uDirectCount);
  return e;
}
)";

}  // namespace

std::string directLightingGlsl() {
  std::string s = cat("const int kMaxDirect = ", kMaxDirectLights, ";\nconst int kMaxShadowLayers = ",
                      kMaxDirectLights * kMaxCascades, ";\n#define kShadowUnit ", kShadowMapUnit,
                      "\nconst int kBlockerSamples = ", kBlockerSamples, ";\nconst int kFilterSamples = ",
                      kFilterSamples, ";\nconst float kMaxKernel = ", kMaxKernelTexels, ".0;\n");
  s += goldenGlsl();
  s += kDirectHeadGlsl;
  return s;
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
