// A MATERIAL pixel's exitant radiance (docs/render.md, "Materials"): after material_inputs.glsl,
// material_shading.glsl and, with DIRECT, direct_specular.glsl.
//   L = diffuse/π · (occlusion · e + E_direct) + Σ_direct highlights
//       + (F0·A + B) · (so · prefiltered environment + (1 − so) · occlusion · e/π) + emission,
//   so = specularOcclusion(n·v, visibility · occlusion)
// e: the transfer's (or the probes') light, all of it indirect or ambient where the direct lights
// are apart, so the occlusion texture darkens it and not the direct lights (glTF: "indirect
// lighting"); visibility: the bake's ambient visibility (1 where it has none).
vec3 materialRadiance(vec3 x, vec3 normal, vec3 e, float visibility, vec3 dxW, vec3 dyW) {
  float side = gl_FrontFacing ? 1.0 : -1.0;  // a double-sided material's back: the normal turned
  vec3 ng = side * normalize(normal);
  Surface s = surfaceAt(ng, side);
  vec3 v = viewDirection(x);
  vec3 diffuseE = e * s.occlusion;
  vec3 spec = vec3(0.0);
#ifdef DIRECT
  vec3 ed, sd;
  directShading(x, ng, s, v, dxW, dyW, ed, sd);
  diffuseE += ed;
  spec += sd;
#endif
  float nv = max(dot(s.n, v), 1e-4);
  float a = s.roughness * s.roughness;
  // The lobe's visible share reflects the environment; the rest the surroundings that hide it,
  // taken at their mean radiance as the diffuse light sees them, e/π (the walls of a room).
  float so = specularOcclusion(nv, visibility * s.occlusion, a);
  vec3 surroundings = e * s.occlusion * 0.31830988618379067;
  spec += splitSumWeight(s, nv) * (so * reflectedEnvironment(s, v) + (1.0 - so) * surroundings);
  return s.diffuse * diffuseE * 0.31830988618379067 + spec + s.emission;
}
