// Receivers: the rest-pose vertex moved by uModel / uNormalMatrix; vWorld, vNormal and the
// material's varyings. @LOOKUP_DECLARATIONS@ and @LOOKUP@: ProbeLookup::PerVertex does the
// probe lookup here and passes the packed incident radiance on (empty for PerPixel).
#version 450 core
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
@LOOKUP_DECLARATIONS@
void main() {
  vec4 world = uModel * vec4(aPosition, 1.0);
  vWorld = world.xyz;
  vWorldPixel = world.xyz;
  vNormal = normalize(uNormalMatrix * aNormal);  // unit world normals per vertex, interpolated
#include "albedo_pass.glsl"
@LOOKUP@
  gl_Position = uViewProj * world;
}
