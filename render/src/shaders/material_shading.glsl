// The glTF BRDF's specular lobe and the light it reflects (MATERIAL variants; docs/render.md,
// "Materials"), after prt::brdf (probes/brdf/include/prt/brdf.h, whose numbered references [1]–[6]
// the comments cite): GGX D, height-correlated Smith V, Schlick F; the dielectric's F0 colour and
// weight from KHR_materials_ior/specular, the metal's F0 its base colour [1, 2]. The environment's
// specular by the split sum [5, 6]: prefiltered radiance (environment_prefilter.h) × (F0·A + B),
// A and B from the DFG table (prt::brdf::computeDfgTable), times a specular occlusion.
// materialRadiance() puts the pixel together. Needs material_inputs.glsl.
#include "common.glsl"
const int kMaxEnvMaps = @MAX_ENV_MAPS@;
#define ENV_MAPS @ENV_MAPS@
uniform vec4 uEye;  // xyz: the camera's position (w = 1) or its view direction towards the scene (w = 0)
uniform mat3 uEnvWorldToMap[kMaxEnvMaps];
uniform vec3 uEnvScale[kMaxEnvMaps];
uniform vec3 uEnvUniform;   // the uniform part of the environment's radiance
uniform float uEnvMaxLod;   // prefiltered layers − 1: layer = roughness × uEnvMaxLod
uniform int uEnvOn;         // 0: no environment reflection (Frame::environment null)
const int kLevels = @LEVELS@;
layout(binding = 17) uniform sampler3D uEnvMaps;  // map i's level k (roughness k / uEnvMaxLod): slice i·kLevels + k
layout(binding = @DFG_UNIT@) uniform sampler2D uDfg;  // (A, B) at (n·v, roughness)

float ggxD(float nh, float a) {
  float a2 = a * a;
  float d = nh * nh * (a2 - 1.0) + 1.0;
  return nh > 0.0 ? a2 / (kPi * d * d) : 0.0;
}

// V = 0.5 / (n·l √((n·v)²(1 − α²) + α²) + n·v √((n·l)²(1 − α²) + α²)) [1, 4].
float smithV(float nl, float nv, float a) {
  float a2 = a * a;
  float gv = nl * sqrt(nv * nv * (1.0 - a2) + a2);
  float gl = nv * sqrt(nl * nl * (1.0 - a2) + a2);
  return 0.5 / max(gv + gl, 1e-12);
}

// The Fresnel weight of the specular lobe, mixed as [1, 2] mix the two materials:
// (1 − metallic)·s·F_d + metallic·F_m, F = F0 + (1 − F0)(1 − v·h)⁵.
vec3 specularFresnel(Surface s, float vh) {
  float c = pow(1.0 - clamp(vh, 0.0, 1.0), 5.0);
  vec3 fd = uSpecularColor.rgb + (1.0 - uSpecularColor.rgb) * c;
  vec3 fm = s.baseColor + (1.0 - s.baseColor) * c;
  return (1.0 - s.metallic) * uSpecularColor.w * fd + s.metallic * fm;
}

// f_spec(l, v) = F · V · D, α = roughness²; 0 where n·l ≤ 0.
vec3 specularBrdf(Surface s, vec3 l, vec3 v, float a) {
  float nl = dot(s.n, l), nv = max(dot(s.n, v), 1e-4);
  if (nl <= 0.0) return vec3(0.0);
  vec3 h = normalize(l + v);
  return specularFresnel(s, dot(v, h)) * (smithV(nl, nv, a) * ggxD(dot(s.n, h), a));
}

// The unit vector from x towards the camera.
vec3 viewDirection(vec3 x) { return uEye.w > 0.0 ? normalize(uEye.xyz - x) : -uEye.xyz; }

// Octahedral coordinates of unit direction m, folded about +Y (environment_prefilter.h,
// octahedralUv): no arc tangent, which cost llvmpipe ≈ 0.15 of a diffuse frame per map.
vec2 octahedralUv(vec3 m) {
  vec2 p = m.xz / (abs(m.x) + abs(m.y) + abs(m.z));
  vec2 sg = vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
  p = m.y < 0.0 ? (1.0 - abs(p.yx)) * sg : p;
  return 0.5 * p + 0.5;
}

// Map i's radiance at fractional level `level` along r: one trilinear lookup blends the two
// slices around it (slice centres at (k + ½)/depth; level ∈ [0, kLevels − 1] keeps it inside the
// map's slices), where two bilinear lookups cost llvmpipe ≈ 0.1 of a diffuse frame more.
vec3 envMap(int i, vec3 r, float level) {
  vec2 uv = octahedralUv(uEnvWorldToMap[i] * r);
  float z = (float(i * kLevels) + level + 0.5) / float(ENV_MAPS * kLevels);
  return uEnvScale[i] * textureLod(uEnvMaps, vec3(uv, z), 0.0).rgb;
}

// The environment's radiance prefiltered by the GGX lobe of `roughness` around r: each map
// between its two levels around roughness × uEnvMaxLod. The map count is compiled in (ENV_MAPS,
// the frame's): a loop or a branch on a uniform count costs llvmpipe the lookups of every map
// it could skip.
vec3 prefilteredRadiance(vec3 r, float roughness) {
  vec3 L = uEnvUniform;
  float level = roughness * uEnvMaxLod;
#if ENV_MAPS > 0
  L += envMap(0, r, level);
#endif
#if ENV_MAPS > 1
  L += envMap(1, r, level);
#endif
#if ENV_MAPS > 2
  L += envMap(2, r, level);
#endif
#if ENV_MAPS > 3
  L += envMap(3, r, level);
#endif
  return L;
}

// Lagarde and de Rousiers 2014 ("Moving Frostbite to PBR", section 4.10.2): the visible share of
// the specular lobe from the ambient visibility `ao` (cosine-weighted), rougher lobes following
// it closer: clamp((n·v + ao)^exp2(−16α − 1) − 1 + ao, 0, 1).
float specularOcclusion(float nv, float ao, float a) {
  return clamp(pow(nv + ao, exp2(-16.0 * a - 1.0)) - 1.0 + ao, 0.0, 1.0);
}

// The DFG table's (A, B) at n·v and the surface's roughness.
vec2 dfgAt(Surface s, float nv) {
  const float n = float(@DFG_SIZE@);  // entries at x = i / (n − 1), texel centres (i + ½) / n
  return texture(uDfg, (vec2(nv, s.roughness) * (n - 1.0) + 0.5) / n).rg;
}
// The metal's share of the lobe's weight, metallic · (baseColor · A + B): what the bake bounces
// of a metal (docs/bake.md, "Materials"), at this view rather than averaged over views.
vec3 metalLobeWeight(Surface s, vec2 ab) { return s.metallic * (s.baseColor * ab.x + ab.y); }
// The split sum's second factor, F0·A + B per lobe, mixed as specularFresnel [5, 6].
vec3 splitSumWeight(Surface s, vec2 ab) {
  vec3 fd = uSpecularColor.rgb * ab.x + ab.y;
  return (1.0 - s.metallic) * uSpecularColor.w * fd + metalLobeWeight(s, ab);
}

// The environment's prefiltered radiance along the reflected view ray (0 without one).
vec3 reflectedEnvironment(Surface s, vec3 v) {
  return uEnvOn == 0 ? vec3(0.0) : prefilteredRadiance(reflect(-v, s.n), s.roughness);
}
