// Direct lights per pixel with PCSS-filtered shadow maps (direct_shading.cpp derives the
// terms): the fragment stage's uniforms, pixelFootprint() and directIrradiance(). The @NAME@
// values are the C++ constants of direct_shading.h and prt/render/renderer.h.
const int kMaxDirect = @MAX_DIRECT@;
const int kMaxShadowLayers = @MAX_SHADOW_LAYERS@;
#define kShadowUnit @SHADOW_UNIT@
const int kBlockerSamples = @BLOCKER_SAMPLES@;
const int kFilterSamples = @FILTER_SAMPLES@;
const float kMaxKernel = @MAX_KERNEL@.0;
// R2 (Roberts 2018): the additive recurrence of the plastic number g = 1.3247179572447460,
// (1/g, 1/g²), even in the unit square.
const vec2 kR2 = vec2(7.548776662e-01, 5.698402910e-01);
// Vogel spiral: point i of n at radius √((i + ½)/n), angle i · golden angle (2.399963229728653
// rad): even density over the unit disk for any n. The loops walk it, turning by kGolden from
// one point to the next.
const mat2 kGolden = mat2(-7.373688781e-01, 6.754902943e-01, -6.754902943e-01, -7.373688781e-01);

in vec3 vWorldPixel;                         // vWorld, interpolated at the pixel's centre
uniform int uDirectCount;
uniform vec4 uDirectDir[kMaxDirect];         // unit direction towards the light, sin² r (0: a delta)
uniform vec4 uDirectIrradiance[kMaxDirect];  // RGB irradiance on a surface facing it, cot r
uniform int uShadowed;                       // 0: every visible share is 1
uniform int uLoopStep;                       // 1; see "Loops" in direct_shading.cpp
uniform int uCascades;
uniform vec4 uCascadeFar;                    // view depth where cascade c ends
uniform vec3 uViewOrigin;
uniform vec3 uViewForward;
uniform int uShadowSize;                     // texels a side
uniform mat4 uShadowMatrix[kMaxShadowLayers];  // world -> map metres (x, y) and depth (z)
uniform vec4 uShadowParams[kMaxShadowLayers];  // texel (m), depth range (m), tan r, 0
layout(binding = kShadowUnit) uniform sampler2DArray uShadowMap;

#include "common.glsl"

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
  float e = (c * atan2Accurate(sq, y) - x * sy) * sin2 + atan2Accurate(sy, x);  // acos y = atan2(√(1 − y²), y)
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

#include "local_lighting.glsl"

// Σ_k E_k · directCosineFactor_k(n) · visibleShare_k(x), a loop over the lights that tests at
// its end, so that one light costs one pass; plus the lights inside the scene (localIrradiance).
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
  return e + localIrradiance(x, n, n);
}
