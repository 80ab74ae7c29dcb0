// The background: each pixel's centre ray (as the orbit and glTF cameras' rays, docs/render.md)
// looks up RigBackground::radiance: the uniform part, up to @MAX_MAPS@ environment maps and
// @MAX_CAPS@ suns and disks (the limits of prt/render/renderer.h).
#version 450 core
const int kMaxMaps = @MAX_MAPS@;
const int kMaxCaps = @MAX_CAPS@;
layout(binding = 4) uniform sampler2D uMaps[kMaxMaps];
uniform mat3 uCamera;            // camera to world rotation
uniform vec2 uTan;               // tan of half the horizontal and vertical fields of view
uniform int uOrtho;              // 1: every ray looks down the camera's -Z
uniform vec2 uViewport;
uniform int uMapCount;
uniform mat3 uWorldToMap[kMaxMaps];
uniform vec3 uMapScale[kMaxMaps];
uniform int uCapCount;
uniform vec4 uCaps[kMaxCaps];         // direction, cos radius
uniform vec4 uCapRadiance[kMaxCaps];
uniform vec3 uUniformRadiance;
out vec4 fragColor;
#include "common.glsl"
void main() {
  vec2 ndc = gl_FragCoord.xy / uViewport * 2.0 - 1.0;
  vec3 dir = uOrtho != 0 ? vec3(0.0, 0.0, -1.0) : vec3(ndc * uTan, -1.0);
  vec3 d = normalize(uCamera * dir);
  vec3 L = uUniformRadiance;
  for (int i = 0; i < kMaxMaps; ++i) {
    if (i >= uMapCount) break;
    vec3 m = uWorldToMap[i] * d;
    // equirectUv (prt/light.h); θ as atan2(√(x² + z²), y), which keeps its precision at the poles.
    vec2 uv = vec2(0.5 + atan2Accurate(m.z, m.x) / (2.0 * kPi), atan2Accurate(length(m.xz), m.y) / kPi);
    L += uMapScale[i] * textureLod(uMaps[i], uv, 0.0).rgb;
  }
  for (int i = 0; i < kMaxCaps; ++i) {
    if (i >= uCapCount) break;
    if (dot(d, uCaps[i].xyz) >= uCaps[i].w) L += uCapRadiance[i].rgb;
  }
  fragColor = vec4(L, 1.0);
}
