// Lights inside the scene per pixel (local_shading.cpp derives the terms): point, spot, sphere,
// disk and rectangle lights, their unoccluded irradiance in closed form (probes/lights'
// localIrradiance, in float) times the visible share read from a cube of shadow maps drawn from
// each light's centre. Included by direct_lighting.glsl; the @NAME@ values are the C++
// constants of local_shading.h.
const int kMaxLocal = @MAX_LOCAL@;
#define kLocalUnit @LOCAL_UNIT@
const int kLocalDiskSides = @DISK_SIDES@;
const int kLocalBlockerSamples = @LOCAL_BLOCKER_SAMPLES@;
const int kLocalFilterSamples = @LOCAL_FILTER_SAMPLES@;
const float kLocalMaxKernel = @LOCAL_MAX_KERNEL@.0;

uniform int uLocalCount;
uniform vec4 uLocalPos[kMaxLocal];     // position, type (0 point, 1 spot, 2 sphere, 3 disk, 4 rectangle)
uniform vec4 uLocalDir[kMaxLocal];     // spot: its axis; disk, rectangle: the emitting side's normal; range (0: none)
uniform vec4 uLocalUp[kMaxLocal];      // rectangle: unit along its height; its width
uniform vec4 uLocalColor[kMaxLocal];   // intensity (point, spot) or radiance (area lights), RGB; rectangle: height
uniform vec4 uLocalShape[kMaxLocal];   // spot: scale, offset of its falloff; radius (sphere, disk; rectangle:
                                       // its half diagonal), the map's near plane
uniform int uLocalShadowed;            // 0: every visible share is 1
uniform int uLocalMapSize;             // texels a side of each cube face
uniform float uLocalFar;               // the maps' far plane (m)
uniform mat4 uLocalMatrix[kMaxLocal * 6];  // world -> clip of each cube face (+X, −X, +Y, −Y, +Z, −Z)
layout(binding = kLocalUnit) uniform sampler2DArray uLocalMap;

#include "common.glsl"

// ∫ max(n·ω, 0) dω over the convex polygon q[0..count) seen from x, clipped by x's horizon
// first (Lambert's formula ½ |Σ_i Θ_i n·Γ_i|), as probes/lights' polygonCosineIntegral.
float polygonCosine(vec3 q[kLocalDiskSides], int count, vec3 x, vec3 n) {
  vec3 c[kLocalDiskSides + 1];
  int m = 0;
  for (int i = 0; i < count; ++i) {
    vec3 a = q[i] - x, b = q[(i + 1) % count] - x;
    float da = dot(a, n), db = dot(b, n);
    if (da >= 0.0) c[m++] = a;
    if ((da >= 0.0) != (db >= 0.0)) c[m++] = a + (b - a) * (da / (da - db));
  }
  float sum = 0.0;
  for (int i = 0; i < m; ++i) {
    vec3 a = normalize(c[i]), b = normalize(c[(i + 1) % m]);
    vec3 g = cross(a, b);
    float s = length(g);
    if (s > 1e-12) sum += atan2Accurate(s, dot(a, b)) * dot(g / s, n);
  }
  return 0.5 * abs(sum);
}

// The unoccluded irradiance of light k at x (normal n), RGB.
vec3 localUnoccluded(int k, vec3 x, vec3 n) {
  vec4 P = uLocalPos[k], D = uLocalDir[k], S = uLocalShape[k];
  int type = int(P.w + 0.5);
  vec3 d = P.xyz - x;
  float r2 = max(dot(d, d), 1e-12), r = sqrt(r2);
  vec3 l = d / r;
  if (type <= 1) {  // point, spot
    float window = D.w > 0.0 ? clamp(1.0 - pow(r / D.w, 4.0), 0.0, 1.0) : 1.0;
    float falloff = 1.0;
    if (type == 1) {
      float f = clamp(dot(D.xyz, -l) * S.x + S.y, 0.0, 1.0);
      falloff = f * f;
    }
    return uLocalColor[k].rgb * (max(dot(n, l), 0.0) / r2 * window * falloff);
  }
  if (type == 2) {  // sphere: π L sin²α times the cap's cosine factor
    if (r <= S.z) return vec3(0.0);
    float sin2 = S.z * S.z / r2;
    float f = directCosineFactor(n, vec4(l, sin2), sqrt(max(1.0 - sin2, 0.0) / sin2));
    return uLocalColor[k].rgb * (kPi * sin2 * f);
  }
  if (dot(x - P.xyz, D.xyz) <= 0.0) return vec3(0.0);  // behind a disk or rectangle
  vec3 q[kLocalDiskSides];
  int count;
  if (type == 3) {  // disk: its area-matched polygon (as probes/lights' kDiskPolygonSides-gon)
    vec3 u = normalize(abs(D.x) < 0.9 ? cross(D.xyz, vec3(1.0, 0.0, 0.0)) : cross(D.xyz, vec3(0.0, 1.0, 0.0)));
    vec3 v = cross(D.xyz, u);
    float step = 2.0 * kPi / float(kLocalDiskSides);
    float rr = S.z * sqrt(step / sin(step));
    for (int i = 0; i < kLocalDiskSides; ++i) q[i] = P.xyz + rr * (cos(float(i) * step) * u + sin(float(i) * step) * v);
    count = kLocalDiskSides;
  } else {  // rectangle
    vec3 up = uLocalUp[k].xyz, across = cross(up, D.xyz);
    vec3 hw = 0.5 * uLocalUp[k].w * across, hh = 0.5 * uLocalColor[k].w * up;
    q[0] = P.xyz - hw - hh;
    q[1] = P.xyz + hw - hh;
    q[2] = P.xyz + hw + hh;
    q[3] = P.xyz - hw + hh;
    count = 4;
  }
  return uLocalColor[k].rgb * polygonCosine(q, count, x, n);
}

// Distance along the face's axis of the nearest caster at map position t (texels) of layer.
float localMapDistance(int layer, vec2 t, float nearPlane) {
  float size = float(uLocalMapSize);
  vec2 i = clamp(floor(t), vec2(0.0), vec2(size - 1.0));
  float depth = textureLod(uLocalMap, vec3((i + 0.5) / size, float(layer)), 0.0).r;
  return uLocalFar * nearPlane / (uLocalFar - depth * (uLocalFar - nearPlane));
}

// The share of light k seen from x (geometric normal ng), from its cube of maps: PCSS about the
// light's centre. A blocker at distance zb from the light, x at zr, hides points of a light of
// radius R up to R (zr − zb) / (zb zr) radians from x's direction seen from the centre: the
// blocker search takes zb ≥ zr / 2 (R / zr radians), the filter the mean blocker's distance.
// Point and spot lights (R = 0): a 1.5-texel filter. Comparisons after moving x 1.5 texels
// along ng (normal offset: no acne on surfaces that face the light at a grazing angle).
float localVisibleShare(int k, vec3 x, vec3 ng) {
  vec3 v0 = x - uLocalPos[k].xyz;
  float size = float(uLocalMapSize);
  float texelAngle = 2.0 / size;
  vec3 x1 = x + ng * (1.5 * texelAngle * length(v0));
  vec3 v = x1 - uLocalPos[k].xyz, a = abs(v);
  int face = a.x >= a.y && a.x >= a.z ? (v.x >= 0.0 ? 0 : 1) : a.y >= a.z ? (v.y >= 0.0 ? 2 : 3) : (v.z >= 0.0 ? 4 : 5);
  float zr = max(max(a.x, a.y), a.z);
  int layer = k * 6 + face;
  vec4 clip = uLocalMatrix[layer] * vec4(x1, 1.0);
  vec2 t = (clip.xy / clip.w * 0.5 + 0.5) * size;
  float nearPlane = uLocalShape[k].w, radius = uLocalShape[k].z;
  float bias = 2.0 * texelAngle * zr;
  float noise = fract(52.9829189 * fract(dot(gl_FragCoord.xy, vec2(0.06711056, 0.00583715))));
  float ang = 6.28318530718 * noise;
  vec2 turn = vec2(cos(ang), sin(ang));
  float search = clamp(radius / zr / texelAngle, 1.5, kLocalMaxKernel);
  float nb = 0.0, sumB = 0.0;
  vec2 dir = turn * search;
  for (int i = 0; i < kLocalBlockerSamples; ++i) {
    float zb = localMapDistance(layer, t + dir * sqrt((float(i) + 0.5) / float(kLocalBlockerSamples)), nearPlane);
    bool b = zb < zr - bias;
    nb += b ? 1.0 : 0.0;
    sumB += b ? zb : 0.0;
    dir = kGolden * dir;
  }
  if (nb == 0.0) return 1.0;
  float zb = sumB / nb;
  float pen = clamp(radius * (zr - zb) / (zb * zr) / texelAngle, 1.5, kLocalMaxKernel);
  float lit = 0.0;
  dir = turn * pen;
  for (int i = 0; i < kLocalFilterSamples; ++i) {
    float z = localMapDistance(layer, t + dir * sqrt((float(i) + 0.5) / float(kLocalFilterSamples)), nearPlane);
    lit += z >= zr - bias ? 1.0 : 0.0;
    dir = kGolden * dir;
  }
  return lit / float(kLocalFilterSamples);
}

// Σ_k E_k(x, n) · visibleShare_k(x) over the lights inside the scene; n the shading normal, ng
// the geometric one (shadow lookups).
vec3 localIrradiance(vec3 x, vec3 n, vec3 ng) {
  vec3 e = vec3(0.0);
  for (int k = 0; k < uLocalCount; ++k) {
    vec3 E = localUnoccluded(k, x, n);
    if (uLocalShadowed != 0 && max(E.r, max(E.g, E.b)) > 0.0) E *= localVisibleShare(k, x, ng);
    e += E;
  }
  return e;
}
