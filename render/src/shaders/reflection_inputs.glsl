// The baked and receiver fragment shaders' outputs: location 0 the pixel's radiance; 1–4 what
// the screen-space reflection pass (reflection_pass.cpp) needs of a MATERIAL pixel's lobe
// (material_radiance.glsl): 1 its weight (F0·A + B)·occlusion and the roughness, 2 the light it
// reflects as drawn (the environment over the visible share, the fill over the hidden one), 3
// the mirror direction (world), 4 the pixel's radiance as a reflection of it shows it (the bake's
// diffuse re-emission with its bounce albedo; alpha 1 where a surface is). A weight of 0 leaves
// the pixel as it is. Frames without the pass draw to location 0 alone.
layout(location = 0) out vec4 fragColor;
layout(location = 1) out vec4 lobeWeight;
layout(location = 2) out vec4 lobeDrawn;
layout(location = 3) out vec4 mirrorDirection;
layout(location = 4) out vec4 bouncedRadiance;
void writeReflectionInputs(vec3 weight, vec3 drawn, vec3 mirror, float roughness, vec3 bounced) {
  lobeWeight = vec4(weight, roughness);
  lobeDrawn = vec4(drawn, 0.0);
  mirrorDirection = vec4(mirror, 0.0);
  bouncedRadiance = vec4(bounced, 1.0);
}
