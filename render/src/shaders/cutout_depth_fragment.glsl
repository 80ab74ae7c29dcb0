// Shadow maps of casters that let light through: a MASK cutout is discarded (coverage()), and a
// fragment of opacity a < 1 blocks with probability a, a hash of its position in the map against
// a (the bake's model: a ray stops with probability equal to the opacity, ray_scene.cpp), which
// the shadow filter turns into a partial shadow.
#version 450 core
#include "albedo_inputs.glsl"
float hash(vec2 p) {  // in [0, 1), per texel
  p = fract(p * vec2(0.1031, 0.1030));
  p += dot(p, p.yx + 33.33);
  return fract((p.x + p.y) * p.x);
}
void main() {
  float a = coverage();
  if (a < 1.0 && a <= hash(gl_FragCoord.xy)) discard;
}
