// Baked instances: e = transfer · light per vertex (shader_sources.cpp explains the two ways
// to the transfer, @TRANSFER@: transfer_attributes.glsl or transfer_storage.glsl). TWO_SIDED
// also computes the back side's e; DIRECT takes the direct lights' SH part off (t⁰ · directSh)
// and adds their gathered bounce; DIRECT and MATERIAL pass the world position and normal on,
// MATERIAL the tangent, the second coordinate set and the ambient visibility.
#version 450 core
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec2 aTexcoord;
layout(location = 2) in vec4 aColor;
uniform mat4 uViewProj;
out vec3 vTransferLight;
#ifdef TWO_SIDED
out vec3 vTransferLightBack;
layout(std430, binding = 1) readonly buffer TransferBack { float transferBack[]; };
#endif
#include "albedo_outputs.glsl"
const int kCoeffsAll = @COEFFS@;
#if defined(DIRECT) || defined(MATERIAL)
layout(location = @NORMAL_ATTRIBUTE@) in vec3 aNormal;
layout(std430, binding = 2) readonly buffer TransferDirect { float transferDirect[]; };
#ifdef TWO_SIDED
layout(std430, binding = 3) readonly buffer TransferDirectBack { float transferDirectBack[]; };
#endif
out vec3 vWorld;
out vec3 vNormal;
#endif
#ifdef DIRECT
layout(std430, binding = 4) readonly buffer DirectBounce { float directBounce[]; };  // RGB per vertex
#ifdef TWO_SIDED
layout(std430, binding = 5) readonly buffer DirectBounceBack { float directBounceBack[]; };
#endif
uniform vec3 uDirectSh[kCoeffsAll];  // the direct lights' SH, through the bounced part only
out vec3 vWorldPixel;
#endif
#ifdef MATERIAL
// The material's per-vertex inputs (material_inputs.glsl) from storage buffers indexed by
// gl_VertexID, as the direct part: the 16 attributes are taken by the transfer at 4 bands.
layout(std430, binding = 6) readonly buffer Tangents { vec4 tangents[]; };
layout(std430, binding = 7) readonly buffer Texcoords1 { vec2 texcoords1[]; };
uniform int uVertexInputs;  // bit 0: tangents, bit 1: texcoords1, bit 2: the direct part (visibility)
out vec4 vTangent;
out vec2 vTexcoord1;
// The ambient visibility for the specular occlusion: the direct part's constant coefficient
// against an unoccluded vertex's, t⁰_0 / (π Y₀₀) (∫ max(n·ω, 0) Y₀₀ dω = π Y₀₀); 1 without it.
out float vVisibility;
// The mean radiance of what hides the sky from the vertex, which the hidden share of a glossy
// lobe reflects: e without its direct part t⁰ · sky (what the surroundings send) over the hidden
// share of the cosine, π (1 − visibility) (no less than 0.1 π: near an open sky the share is
// small and so is its weight); e/π without the direct part.
out vec3 vFill;
uniform vec3 uSkySh[kCoeffsAll];  // the light whose direct part t⁰ · uSkySh is in e
#ifdef TWO_SIDED
out float vVisibilityBack;
out vec3 vFillBack;
#endif
#endif
#ifdef MATERIAL
// vFill for light e, from the front (side 0) or the back (1) direct part.
vec3 surroundingsRadiance(vec3 e, uint side) {
  const float kUnoccluded = 0.886226925452758;  // π Y₀₀
  if ((uVertexInputs & 4) == 0) return e * 0.31830988618379067;
  uint base = uint(gl_VertexID) * uint(kCoeffsAll);
  vec3 direct = vec3(0.0);
  float t0 = 0.0;
  for (int i = 0; i < kCoeffsAll; ++i) {
#ifdef TWO_SIDED
    float t = side == 0u ? transferDirect[base + uint(i)] : transferDirectBack[base + uint(i)];
#else
    float t = transferDirect[base + uint(i)];
#endif
    direct += t * uSkySh[i];
    if (i == 0) t0 = t;
  }
  float hidden = max(1.0 - clamp(t0 / kUnoccluded, 0.0, 1.0), 0.1);
  return max(e - direct, vec3(0.0)) / (3.14159265358979 * hidden);
}
#endif
@TRANSFER@
#ifdef DIRECT
  uint baseDirect = uint(gl_VertexID) * uint(kCoeffsAll);
  vec3 d0 = vec3(0.0);
  for (int i = 0; i < kCoeffsAll; ++i) d0 += transferDirect[baseDirect + uint(i)] * uDirectSh[i];
  uint baseBounce = uint(gl_VertexID) * 3u;
  vTransferLight += vec3(directBounce[baseBounce], directBounce[baseBounce + 1u], directBounce[baseBounce + 2u]) - d0;
#ifdef TWO_SIDED
  vec3 d0b = vec3(0.0);
  for (int i = 0; i < kCoeffsAll; ++i) d0b += transferDirectBack[baseDirect + uint(i)] * uDirectSh[i];
  vTransferLightBack += vec3(directBounceBack[baseBounce], directBounceBack[baseBounce + 1u],
                             directBounceBack[baseBounce + 2u]) - d0b;
#endif
  vWorldPixel = aPosition;
#endif
#if defined(DIRECT) || defined(MATERIAL)
  vWorld = aPosition;
  vNormal = aNormal;
#endif
#ifdef MATERIAL
  vTangent = (uVertexInputs & 1) != 0 ? tangents[gl_VertexID] : vec4(0.0);
  vFill = surroundingsRadiance(vTransferLight, 0u);
#ifdef TWO_SIDED
  vFillBack = surroundingsRadiance(vTransferLightBack, 1u);
#endif
  vTexcoord1 = (uVertexInputs & 2) != 0 ? texcoords1[gl_VertexID] : vec2(0.0);
  const float kUnoccluded = 0.886226925452758;  // π Y₀₀
  uint baseVisibility = uint(gl_VertexID) * uint(kCoeffsAll);
  vVisibility = (uVertexInputs & 4) != 0 ? clamp(transferDirect[baseVisibility] / kUnoccluded, 0.0, 1.0) : 1.0;
#ifdef TWO_SIDED
  vVisibilityBack =
      (uVertexInputs & 4) != 0 ? clamp(transferDirectBack[baseVisibility] / kUnoccluded, 0.0, 1.0) : 1.0;
#endif
#endif
#include "albedo_pass.glsl"
  gl_Position = uViewProj * vec4(aPosition, 1.0);
}
