// Baked instances: albedo / π × e per pixel, the alpha the opacity (coverage()). TWO_SIDED: the
// back side's e where the back of the triangle is seen. DIRECT: plus the direct lights per pixel
// (@DIRECT_LIGHTING@: direct_lighting.glsl). MATERIAL: the glTF material instead
// (materialRadiance, @MATERIAL_SHADING@: material_shading.glsl).
#version 450 core
centroid in vec3 vTransferLight;
#ifdef TWO_SIDED
centroid in vec3 vTransferLightBack;
#endif
#if defined(DIRECT) || defined(MATERIAL)
centroid in vec3 vWorld;
centroid in vec3 vNormal;
#endif
#ifdef DIRECT
@DIRECT_LIGHTING@
#endif
#include "albedo_inputs.glsl"
#ifdef MATERIAL
centroid in float vVisibility;
centroid in vec3 vFill;
#ifdef TWO_SIDED
centroid in float vVisibilityBack;
centroid in vec3 vFillBack;
#endif
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
#ifdef TWO_SIDED
  vec3 e = gl_FrontFacing ? vTransferLight : vTransferLightBack;
#else
  vec3 e = vTransferLight;
#endif
#ifdef MATERIAL
#ifdef TWO_SIDED
  float visibility = gl_FrontFacing ? vVisibility : vVisibilityBack;
  vec3 fill = gl_FrontFacing ? vFill : vFillBack;
#else
  float visibility = vVisibility;
  vec3 fill = vFill;
#endif
  fragColor = vec4(materialRadiance(vWorld, vNormal, e, visibility, fill, dxW, dyW), a);
  writeReflectionInputs(gLobeWeight, gLobeDrawn, gMirror, gRoughness, gBounced);
  return;
#endif
#ifdef DIRECT
  vec3 n = normalize(vNormal);
#ifdef TWO_SIDED
  n = gl_FrontFacing ? n : -n;
#endif
  e += directIrradiance(vWorld, n, dxW, dyW);
#endif
  fragColor = vec4(albedo() * e * 0.31830988618379067, a);
  writeReflectionInputs(vec3(0.0), vec3(0.0), vec3(0.0, 0.0, 1.0), 1.0, fragColor.rgb);
}
