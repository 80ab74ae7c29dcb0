// The glTF metallic-roughness material at a pixel (MATERIAL variants; docs/render.md,
// "Materials"): surfaceAt() reads the factors, the metallic-roughness texture (G roughness, B
// metallic), the normal map in the tangent frame, the occlusion texture (R) and the emission.
// A slot's texture is read only where uSlots names its coordinate set (0: vTexcoord, 1:
// vTexcoord1); the renderer leaves a slot at -1 where the texture or its coordinates are
// missing (and says so in a warning), so the factor alone stands. Needs albedo_inputs.glsl.
centroid in vec4 vTangent;    // world tangent (xyz) and handedness (w); unread without a normal map
centroid in vec2 vTexcoord1;  // the material's second coordinate set
uniform vec4 uMaterial;       // metallicFactor, roughnessFactor, normal scale, occlusion strength
uniform vec3 uEmissive;       // emissiveFactor × KHR_materials_emissive_strength
uniform vec4 uSpecularColor;  // the dielectric's F0 colour (rgb) and specular weight (w); 0: no specular
uniform float uDiffuseScale;  // the dielectric's diffuse share against the default one (prt::diffuseScale)
uniform ivec4 uSlots;         // metallic-roughness, normal, occlusion, emissive: coordinate set, -1 none
layout(binding = 13) uniform sampler2D uMetallicRoughnessTexture;
layout(binding = 14) uniform sampler2D uNormalTexture;
layout(binding = 15) uniform sampler2D uOcclusionTexture;
layout(binding = 16) uniform sampler2D uEmissiveTexture;

// Perceptual roughness is clamped to 0.045 (Filament's floor for float maths: α² stays normal).
const float kMinRoughness = 0.045;

struct Surface {
  vec3 diffuse;     // the diffuse albedo: baseColor·(1 − metallic)·uDiffuseScale
  vec3 baseColor;   // the metal's F0
  float metallic;
  float roughness;  // perceptual, clamped
  vec3 n;           // shading normal (normal-mapped), unit
  float occlusion;  // 1 + strength·(texture R − 1)
  vec3 emission;
};

vec2 slotUv(int set) {
#ifdef HAS_TEXCOORD
  return set == 1 ? vTexcoord1 : vTexcoord;
#else
  return vTexcoord1;
#endif
}

// The normal map's normal: the texel's (x, y) scaled by the material's normal scale, in the
// frame (T, B = w · ng × T, ng) with T orthogonalised against ng; the geometric normal where the
// interpolated tangent has no component off it.
vec3 mappedNormal(vec3 ng, float side) {
#ifndef MATERIAL_TEXTURES
  return ng;
#endif
  if (uSlots.y < 0) return ng;
  vec3 t = vTangent.xyz - ng * dot(ng, vTangent.xyz);
  if (dot(t, t) < 1e-12) return ng;
  t = normalize(t);
  vec3 tn = texture(uNormalTexture, slotUv(uSlots.y)).xyz * 2.0 - 1.0;
  tn.xy *= uMaterial.z;
  // The frame of the front side; a back side seen (side −1) mirrors the whole normal.
  vec3 nf = side * ng;
  vec3 b = (vTangent.w < 0.0 ? -1.0 : 1.0) * cross(nf, t);
  vec3 n = t * tn.x + b * tn.y + nf * max(tn.z, 0.0);
  return dot(n, n) > 1e-12 ? side * normalize(n) : ng;
}

// ng: the unit geometric normal of the side seen; side: +1 front, −1 back.
Surface surfaceAt(vec3 ng, float side) {
  Surface s;
  vec3 base = albedo();
  float metallic = uMaterial.x, roughness = uMaterial.y;
  s.occlusion = 1.0;
  s.emission = uEmissive;
#ifdef MATERIAL_TEXTURES  // the slots' lookups only where the material has a texture in one
  if (uSlots.x >= 0) {
    vec4 mr = texture(uMetallicRoughnessTexture, slotUv(uSlots.x));
    roughness *= mr.g;
    metallic *= mr.b;
  }
  if (uSlots.z >= 0) s.occlusion = 1.0 + uMaterial.w * (texture(uOcclusionTexture, slotUv(uSlots.z)).r - 1.0);
  if (uSlots.w >= 0) s.emission *= texture(uEmissiveTexture, slotUv(uSlots.w)).rgb;
#endif
  metallic = clamp(metallic, 0.0, 1.0);
  s.baseColor = base;
  s.metallic = metallic;
  s.roughness = clamp(roughness, kMinRoughness, 1.0);
  s.diffuse = base * (1.0 - metallic) * uDiffuseScale;
  s.n = mappedNormal(ng, side);
  return s;
}
