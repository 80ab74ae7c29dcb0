// Receivers lit from a probe grid on the GPU (private header of render/): the GLSL port of
// prt::probeWeights + interpolateRadiance + sh::irradiance, and the packing of a ProbeGrid into
// the buffers the shader reads (docs/render.md, "Receivers").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "prt/probe_grid.h"
#include "prt/render/renderer.h"
#include "prt/sh.h"

namespace prt::render {

/// GLSL of the fragment shaders (baked and receivers): the material's inputs,
/// albedo() = baseColorFactor × baseColorTexture(texcoord) × COLOR_0, and coverage(), which
/// discards a MASK cutout and returns the opacity (alpha × (1 − transmission)). Texcoords and colours are
/// read only in the variants compiled with HAS_TEXTURE / HAS_COLOR defined (withMaterialDefines):
/// a material without them interpolates no varyings for them and runs no branch. Fragment inputs
/// are `centroid` everywhere: with multisampling, a pixel on an edge is shaded at its covered
/// samples' centroid instead of its centre, which may lie outside the triangle (extrapolated
/// attributes); without it, or in a covered pixel, the centroid is the centre.
inline constexpr const char* kAlbedoInputsGlsl = R"(#ifdef HAS_TEXCOORD
centroid in vec2 vTexcoord;
#endif
#ifdef HAS_TEXTURE
layout(binding = 0) uniform sampler2D uBaseColorTexture;
#endif
#ifdef HAS_TRANSMISSION_TEXTURE
layout(binding = 6) uniform sampler2D uTransmissionTexture;  // KHR_materials_transmission, R
#endif
#ifdef HAS_COLOR
centroid in vec4 vColor;
#endif
uniform vec4 uBaseColor;
vec3 albedo() {
  vec3 a = uBaseColor.rgb;
#ifdef HAS_COLOR
  a *= vColor.rgb;
#endif
#ifdef HAS_TEXTURE
  a *= texture(uBaseColorTexture, vTexcoord).rgb;
#endif
  return a;
}
#if defined(HAS_MASK) || defined(HAS_BLEND)
float baseAlpha() {
  float a = uBaseColor.a;
#ifdef HAS_COLOR
  a *= vColor.a;
#endif
#ifdef HAS_TEXTURE
  a *= texture(uBaseColorTexture, vTexcoord).a;
#endif
  return a;
}
#endif
#ifdef HAS_MASK
uniform float uAlphaCutoff;
#endif
uniform float uOpacity;  // 1 − transmissionFactor
// 1 − transmission: transmissionFactor × the transmission texture's R where it has one.
float opacity() {
#ifdef HAS_TRANSMISSION_TEXTURE
  return 1.0 - (1.0 - uOpacity) * clamp(texture(uTransmissionTexture, vTexcoord).r, 0.0, 1.0);
#else
  return uOpacity;
#endif
}
// The fragment's opacity, the alpha it is blended with; a MASK cutout is discarded here.
float coverage() {
#ifdef HAS_MASK
  if (baseAlpha() < uAlphaCutoff) discard;
#endif
#ifdef HAS_BLEND
  return clamp(baseAlpha(), 0.0, 1.0) * opacity();
#else
  return opacity();
#endif
}
)";

// The vertex shaders' side of kAlbedoInputsGlsl: declarations, and the copies in main().
inline constexpr const char* kAlbedoOutputsGlsl = R"(#ifdef HAS_TEXCOORD
out vec2 vTexcoord;
#endif
#ifdef HAS_COLOR
out vec4 vColor;
#endif
)";
inline constexpr const char* kAlbedoPassGlsl = R"(#ifdef HAS_TEXCOORD
  vTexcoord = aTexcoord;
#endif
#ifdef HAS_COLOR
  vColor = aColor;
#endif
)";

/// Material variant of a shader: bit kVariantTexture (base colour texture sampled), bit
/// kVariantColor (COLOR_0 present), bit kVariantMask (alphaMode MASK: cutouts discarded), bit
/// kVariantBlend (alphaMode BLEND: the alpha is the fragment's opacity), bit kVariantTwoSided (a
/// baked double-sided instance with back-side transfer: each fragment is shaded with the side
/// it is seen from), bit kVariantDirect (direct lights lit per pixel with shadow maps:
/// direct_shading.h), bit kVariantTransmission (KHR_materials_transmission's texture sampled:
/// the opacity is 1 − factor × its R).
constexpr int kVariantTexture = 1, kVariantColor = 2, kVariantMask = 4, kVariantBlend = 8, kVariantTwoSided = 16,
              kVariantDirect = 32, kVariantTransmission = 64, kVariants = 128;
/// `source` (starting with its #version line) with HAS_TEXTURE / HAS_COLOR / HAS_MASK /
/// HAS_BLEND / TWO_SIDED / DIRECT defined after that line as `variant` says.
std::string withMaterialDefines(const std::string& source, int variant);

/// Texels per probe in the static buffer (probeStaticTexels).
constexpr int kProbeStaticTexels = 6;

/// Coefficient indices j < bands² whose band l has a non-zero clamped-cosine factor Â_l (odd
/// l > 1 contribute nothing to irradiance, so the shader never reads them).
std::vector<int> irradianceCoefficients(int bands);

/// RGBA texels per probe in the per-frame radiance buffer: ⌈3K/4⌉ for the K coefficients of
/// irradianceCoefficients(bands).
int radianceTexels(int bands);
/// Packs relit probes (relightProbes' layout: probe-major, bands² RGB) into that buffer: probe p
/// at texels (p + 1) · radianceTexels(bands) on (the null probe 0 is zero), coefficient
/// irradianceCoefficients()[k] at floats 3k..3k+2 of the probe's texels.
void packRadiance(int bands, const std::vector<glm::vec3>& relit, std::vector<glm::vec4>& out);

/// The receivers' shaders for a grid of `bands` bands, to be compiled through
/// withMaterialDefines; uniforms and bindings as set up by Renderer (renderer.cpp). The vertex
/// shader moves the rest-pose vertex by uModel / uNormalMatrix and passes vWorld, vNormal and the
/// material's varyings. ProbeLookup::PerPixel: the fragment shader does the probe lookup at the
/// interpolated x and n. PerVertex: the vertex shader does it at the vertex and passes the
/// normalised incident radiance (packed, radianceTexels vec4) on, interpolated; the fragment shader
/// applies the irradiance basis at the interpolated normal.
std::string receiverVertexShader(int bands, ProbeLookup lookup);
std::string receiverFragmentShader(int bands, ProbeLookup lookup);

/// The light packed as packRadiance packs one probe (radianceTexels(bands) texels).
std::vector<glm::vec4> packLight(int bands, const sh::ShRgb& light);

/// Per probe p, kProbeStaticTexels RGBA texels from texel (p + 1) · kProbeStaticTexels on (the
/// null probe 0 is all zero: validity 0): (position xyz, validity); then for the four sign pairs
/// (s_x, s_y), texel 1 + s_x + 2 s_y (s = 1 on the − side): (μ, σ²) of x's face of side s_x and
/// of y's face of side s_y; then (μ₊, σ²₊, μ₋, σ²₋) of z. The shader reads the position texel,
/// one x-y texel and the z texel: 3 fetches per probe instead of 4 with one texel per axis.
/// σ² = max(m₂ − μ², floor²) is evaluated in double as probeWeights does (a float shader would
/// lose σ² to cancellation).
std::vector<glm::vec4> probeStaticTexels(const ProbeGrid& grid);

/// Dense lattice (index (z·dims.y + y)·dims.x + x) -> position in grid.coord plus one, 0 for none.
std::vector<int32_t> latticeIndex(const ProbeGrid& grid);

/// (0.01 · min spacing)²: the variance floor of probeWeights.
double varianceFloor(const ProbeGrid& grid);
/// 10⁻⁶ · min spacing: below this distance from a probe, probeWeights drops the back-face term.
double nearZero(const ProbeGrid& grid);

}  // namespace prt::render
