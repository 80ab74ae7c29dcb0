// Baked instances: albedo / π × e per pixel, the alpha the opacity (coverage()). TWO_SIDED: the
// back side's e where the back of the triangle is seen. DIRECT: plus the direct lights per pixel
// (@DIRECT_LIGHTING@: direct_lighting.glsl).
#version 450 core
centroid in vec3 vTransferLight;
#ifdef TWO_SIDED
centroid in vec3 vTransferLightBack;
#endif
#ifdef DIRECT
centroid in vec3 vWorld;
centroid in vec3 vNormal;
@DIRECT_LIGHTING@
#endif
#include "albedo_inputs.glsl"
out vec4 fragColor;
void main() {
#ifdef DIRECT
  vec3 dxW, dyW;
  pixelFootprint(dxW, dyW);
#endif
  float a = coverage();
#ifdef TWO_SIDED
  vec3 e = gl_FrontFacing ? vTransferLight : vTransferLightBack;
#else
  vec3 e = vTransferLight;
#endif
#ifdef DIRECT
  vec3 n = normalize(vNormal);
#ifdef TWO_SIDED
  n = gl_FrontFacing ? n : -n;
#endif
  e += directIrradiance(vWorld, n, dxW, dyW);
#endif
  fragColor = vec4(albedo() * e * 0.31830988618379067, a);
}
