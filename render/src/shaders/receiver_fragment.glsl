// Receivers: albedo / π × E with E = irradiance(T, n) (irradiance.glsl) of the incident radiance
// T, found by the probe lookup here (PER_VERTEX_LOOKUP 0, ProbeLookup::PerPixel; @PROBE_LOOKUP@:
// probe_lookup.glsl) or interpolated from the vertices' lookups (PER_VERTEX_LOOKUP 1,
// ProbeLookup::PerVertex; @TEXELS@ packed texels). DIRECT: plus the direct lights per pixel
// (direct_lighting.glsl). MATERIAL: the glTF material (material_radiance.glsl) with the
// probes' irradiance at the normal-mapped normal.
#version 450 core
#define PER_VERTEX_LOOKUP @PER_VERTEX@
centroid in vec3 vWorld;
centroid in vec3 vNormal;
#include "albedo_inputs.glsl"
#if PER_VERTEX_LOOKUP
const int kTexels = @TEXELS@;
centroid in vec4 vRadiance[kTexels];
#else
@PROBE_LOOKUP@
#endif
#include "irradiance.glsl"
#ifdef DIRECT
@DIRECT_LIGHTING@
#endif
#ifdef MATERIAL
#include "material_inputs.glsl"
@MATERIAL_SHADING@
#ifdef DIRECT
#include "direct_specular.glsl"
#endif
#include "material_radiance.glsl"
#endif
#include "reflection_inputs.glsl"
void main() {
#ifdef DIRECT
  vec3 dxW, dyW;
  pixelFootprint(dxW, dyW);
#elif defined(MATERIAL)
  vec3 dxW = vec3(0.0), dyW = vec3(0.0);
#endif
  float a = coverage();
  vec3 n = normalize(vNormal);
#ifdef MATERIAL
  // The probes' irradiance at the shading normal, which the normal map turns; no visibility
  // for the specular occlusion but the occlusion texture's (the probes hold radiance only).
  n = surfaceAt((gl_FrontFacing ? 1.0 : -1.0) * n, gl_FrontFacing ? 1.0 : -1.0).n;
#endif
#if PER_VERTEX_LOOKUP
  vec3 e = irradiance(vRadiance, n);
#else
  vec4 T[kTexels];
  incidentRadiance(vWorld, n, T);
  vec3 e = irradiance(T, n);
#endif
#ifdef MATERIAL
  fragColor = vec4(materialRadiance(vWorld, vNormal, e, 1.0, e * 0.31830988618379067, dxW, dyW), a);
  writeReflectionInputs(gLobeWeight, gLobeDrawn, gMirror, gRoughness, gBounced);
  return;
#endif
#ifdef DIRECT
  e += directIrradiance(vWorld, n, dxW, dyW);
#endif
  fragColor = vec4(albedo() * e * 0.31830988618379067, a);
  writeReflectionInputs(vec3(0.0), vec3(0.0), vec3(0.0, 0.0, 1.0), 1.0, fragColor.rgb);
}
