// Receivers: albedo / π × E with E = irradiance(T, n) (irradiance.glsl) of the incident radiance
// T, found by the probe lookup here (PER_VERTEX_LOOKUP 0, ProbeLookup::PerPixel; @PROBE_LOOKUP@:
// probe_lookup.glsl) or interpolated from the vertices' lookups (PER_VERTEX_LOOKUP 1,
// ProbeLookup::PerVertex; @TEXELS@ packed texels). DIRECT: plus the direct lights per pixel
// (direct_lighting.glsl).
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
out vec4 fragColor;
void main() {
#ifdef DIRECT
  vec3 dxW, dyW;
  pixelFootprint(dxW, dyW);
#endif
  float a = coverage();
  vec3 n = normalize(vNormal);
#if PER_VERTEX_LOOKUP
  vec3 e = irradiance(vRadiance, n);
#else
  vec4 T[kTexels];
  incidentRadiance(vWorld, n, T);
  vec3 e = irradiance(T, n);
#endif
#ifdef DIRECT
  e += directIrradiance(vWorld, n, dxW, dyW);
#endif
  fragColor = vec4(albedo() * e * 0.31830988618379067, a);
}
