// Baked instances: e = transfer · light per vertex (shader_sources.cpp explains the two ways
// to the transfer, @TRANSFER@: transfer_attributes.glsl or transfer_storage.glsl). TWO_SIDED
// also computes the back side's e; DIRECT takes the direct lights' SH part off (t⁰ · directSh)
// and adds their gathered bounce, and passes the world position and normal on.
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
#ifdef DIRECT
layout(location = @NORMAL_ATTRIBUTE@) in vec3 aNormal;
layout(std430, binding = 2) readonly buffer TransferDirect { float transferDirect[]; };
layout(std430, binding = 4) readonly buffer DirectBounce { float directBounce[]; };  // RGB per vertex
#ifdef TWO_SIDED
layout(std430, binding = 3) readonly buffer TransferDirectBack { float transferDirectBack[]; };
layout(std430, binding = 5) readonly buffer DirectBounceBack { float directBounceBack[]; };
#endif
uniform vec3 uDirectSh[kCoeffsAll];  // the direct lights' SH, through the bounced part only
out vec3 vWorld;
out vec3 vWorldPixel;
out vec3 vNormal;
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
  vWorld = aPosition;
  vWorldPixel = aPosition;
  vNormal = aNormal;
#endif
#include "albedo_pass.glsl"
  gl_Position = uViewProj * vec4(aPosition, 1.0);
}
