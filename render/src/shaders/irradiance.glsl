// receiver_fragment.glsl's irradiance(T, n) = Σ_j Â_l y_j(n) c_j, n unit, T the packed radiance
// (probe_shading.cpp): @IRRADIANCE_BASIS@ sets float b<j> = Â_l y_j(n) for the coefficients j
// with Â_l ≠ 0, unrolled over the bands; @IRRADIANCE_SUMS@ adds each c_j (RGB, from the texels'
// lanes) times b<j>.

vec3 irradiance(vec4 T[kTexels], vec3 n) {
  float px = n.x, py = n.y, pz = n.z;
@IRRADIANCE_BASIS@
  vec3 e = vec3(0.0);
@IRRADIANCE_SUMS@
  return e;
}
