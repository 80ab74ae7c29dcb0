// Shadow maps of casters that let light through (MASK, BLEND, transmission): positions and the
// material's varyings.
#version 450 core
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec2 aTexcoord;
layout(location = 2) in vec4 aColor;
uniform mat4 uViewProj;
uniform mat4 uModel;
#include "albedo_outputs.glsl"
void main() {
#include "albedo_pass.glsl"
  gl_Position = uViewProj * (uModel * vec4(aPosition, 1.0));
}
