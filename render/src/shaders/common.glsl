// Maths shared by the shaders (guarded: the material and direct-light files both include it).
#ifndef PRT_COMMON_GLSL
#define PRT_COMMON_GLSL
const float kPi = 3.14159265358979;
// atan(y, x) to about float's precision: GLSL's atan and acos are polynomial approximations
// (Mesa's acos is off by up to ~1e-4 rad, a visible fraction of a texel in a large map).
// Cephes' atanf: |t| <= tan(π/8) by atan t = π/4 + atan((t − 1)/(t + 1)), then an odd
// polynomial; the octant from the signs and which of |x|, |y| is larger.
float atan2Accurate(float y, float x) {
  float ax = abs(x), ay = abs(y);
  float t = min(ax, ay) / max(max(ax, ay), 1e-30);
  bool reduce = t > 0.41421356;
  float r = reduce ? (t - 1.0) / (t + 1.0) : t;
  float z = r * r;
  float a = (((8.05374449538e-2 * z - 1.38776856032e-1) * z + 1.99777106478e-1) * z - 3.33329491539e-1) * z * r + r;
  a += reduce ? 0.78539816339 : 0.0;
  a = ay > ax ? 1.57079632679 - a : a;
  a = x < 0.0 ? kPi - a : a;
  return y < 0.0 ? -a : a;
}
#endif
