// Receivers: albedo / π × E with E the irradiance from the probes (@LOOKUP_DECLARATIONS@: the
// lookup, PerPixel, or the interpolated radiance, PerVertex; @IRRADIANCE@: irradiance(T, n);
// @RADIANCE@: e at the pixel). DIRECT: plus the direct lights per pixel (direct_lighting.glsl).
#version 450 core
centroid in vec3 vWorld;
centroid in vec3 vNormal;
#include "albedo_inputs.glsl"
@LOOKUP_DECLARATIONS@
@IRRADIANCE@
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
@RADIANCE@
#ifdef DIRECT
  e += directIrradiance(vWorld, n, dxW, dyW);
#endif
  fragColor = vec4(albedo() * e * 0.31830988618379067, a);
}
