// Receivers: the rest-pose vertex moved by uModel / uNormalMatrix; vWorld, vNormal and the
// material's varyings. PER_VERTEX_LOOKUP (@PER_VERTEX@: 1 for ProbeLookup::PerVertex, 0 for
// PerPixel): the probe lookup (@PROBE_LOOKUP@: probe_lookup.glsl) runs here, at the vertex, and
// the packed incident radiance it finds is passed on, interpolated.
#version 450 core
#define PER_VERTEX_LOOKUP @PER_VERTEX@
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec2 aTexcoord;
layout(location = 2) in vec4 aColor;
layout(location = 3) in vec3 aNormal;
uniform mat4 uViewProj;
uniform mat4 uModel;
uniform mat3 uNormalMatrix;
out vec3 vWorld;
out vec3 vWorldPixel;  // vWorld for the footprint's derivatives (direct_shading.cpp); unread without direct lights
out vec3 vNormal;
#include "albedo_outputs.glsl"
#ifdef MATERIAL
layout(location = 4) in vec4 aTangent;    // world tangent at rest, handedness w
layout(location = 5) in vec2 aTexcoord1;  // the material's second coordinate set
out vec4 vTangent;
out vec2 vTexcoord1;
#endif
#if PER_VERTEX_LOOKUP
@PROBE_LOOKUP@
out vec4 vRadiance[kTexels];
#endif
void main() {
  vec4 world = uModel * vec4(aPosition, 1.0);
  vWorld = world.xyz;
  vWorldPixel = world.xyz;
  vNormal = normalize(uNormalMatrix * aNormal);  // unit world normals per vertex, interpolated
#include "albedo_pass.glsl"
#ifdef MATERIAL
  vTangent = vec4(mat3(uModel) * aTangent.xyz, aTangent.w);  // a tangent moves as the surface does
  vTexcoord1 = aTexcoord1;
#endif
#if PER_VERTEX_LOOKUP
  vec4 T[kTexels];
  incidentRadiance(vWorld, vNormal, T);
  vRadiance = T;
#endif
  gl_Position = uViewProj * world;
}
