// prt::probeWeights (probes/grid/src/probe_grid.cpp) ported step by step, without branches
// (probe_shading.cpp explains the port). @CORNER_SETUP@ and @CORNER_WEIGHTS@ are the loops over
// the cell's 8 corners, unrolled from probe_corner_setup.glsl and probe_corner_weight.glsl.

// BEGIN probeWeights port.
const float kBoundaryTolerance = 1e-4;
const float kDomainMargin = 0.5;  // the domain: the lattice's box grown by half a cell
const float kFadeSpacings = 1.0;  // beyond it, the probes fade into the light over one cell
const float kMinWeight = 1e-6;
const float kTrilinearFloor = 1e-3;

// prt::ProbeGrid::find, plus one: 0 where the lattice point has no probe or lies outside.
int findProbe(ivec3 q) {
  bool inside = all(greaterThanEqual(q, ivec3(0))) && all(lessThan(q, uDims));
  ivec3 c = clamp(q, ivec3(0), uDims - 1);
  int p = texelFetch(uLattice, (c.z * uDims.y + c.y) * uDims.x + c.x).r;
  return inside ? p : 0;
}

// Chebyshev visibility (cubed) on one axis: m = (μ, σ²) of face 2a + (d_a < 0), the mean and
// floored variance of the depth along axis a; the receiver's depth is |d_a|.
float axisVisibility(vec2 m, float depth) {
  float cheb = m.y / (m.y + (depth - m.x) * (depth - m.x));
  return depth <= m.x ? 1.0 : cheb * cheb * cheb;
}

// Visibility times the soft back-face weight, floored: d = x − P, r = |d|. All three axes must
// pass. The faces of x and y come in one texel per sign pair (probeStaticTexels), z's in one.
float leakWeight(int p, vec3 d, float r, vec3 n) {
  vec4 xy = texelFetch(uProbeStatic, p * kStaticTexels + 1 + (d.x < 0.0 ? 1 : 0) + (d.y < 0.0 ? 2 : 0));
  vec4 z = texelFetch(uProbeStatic, p * kStaticTexels + 5);
  float wv = axisVisibility(xy.xy, abs(d.x)) * axisVisibility(xy.zw, abs(d.y)) *
             axisVisibility(d.z < 0.0 ? z.zw : z.xy, abs(d.z));
  float h = (dot(-d / max(r, 1e-30), n) + 1.0) * 0.5;
  float wb = r > uNearZero ? h * h + 0.2 : 1.0;
  return max(wv * wb, kMinWeight);
}

float probeWeights(vec3 x, vec3 n, out int probe[8], out float weight[8], out float fade) {
  vec3 u = (x - uOrigin) / uSpacing;
  vec3 hi = vec3(uDims - 1);
  const float margin = kDomainMargin + kFadeSpacings + kBoundaryTolerance;
  bool inside = all(greaterThan(u, vec3(-margin))) &&
                all(lessThan(u, hi + margin));  // false for NaN too
  vec3 over3 = max(vec3(-kDomainMargin) - u, u - (hi + kDomainMargin));
  float over = max(max(max(over3.x, over3.y), over3.z), 0.0);
  fade = clamp((over - kBoundaryTolerance) / kFadeSpacings, 0.0, 1.0);
  vec3 v = clamp(u, vec3(0.0), hi);
  ivec3 base = min(ivec3(floor(v)), max(uDims - 2, ivec3(0)));
  vec3 t = v - vec3(base);
  vec3 lerp[8];
  vec4 pv[8];  // (position, validity), validity 0 for no or an invalid probe
  bool anyTrilinear = false;
@CORNER_SETUP@
  float sum = 0.0;
@CORNER_WEIGHTS@
  return inside ? sum : 0.0;
}
// END probeWeights port.
