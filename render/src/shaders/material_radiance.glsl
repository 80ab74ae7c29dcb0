// A MATERIAL pixel's exitant radiance (docs/render.md, "Materials"): after material_inputs.glsl,
// material_shading.glsl and, with DIRECT, direct_specular.glsl.
//   L = diffuse/π · (occlusion · e + E_direct) + Σ_direct highlights
//       + (F0·A + B) · (so · prefiltered environment + (1 − so) · occlusion · fill) + emission,
//   so = specularOcclusion(n·v, visibility · occlusion)
// e: the transfer's (or the probes') light, all of it indirect or ambient where the direct lights
// are apart, so the occlusion texture darkens it and not the direct lights (glTF: "indirect
// lighting"); visibility: the bake's ambient visibility (1 where it has none); fill: the mean
// radiance of what hides the sky (baked_vertex.glsl's vFill; e/π for receivers).
// ROUGH_SPECULAR (roughness ≥ kRoughSpecularRoughness, shader_variants.h): the environment's
// specular is (F0·A + B) · occlusion · e/π, no lookup: at roughness 1 the split sum's prefiltered
// lobe (n = v = r, weighted by n·l) is the cosine lobe around r, whose mean radiance is E(r)/π;
// e is that mean around n, with the bake's occlusion and interreflection in it.
// The lobe's weight (F0·A + B)·occlusion, the light it reflects as drawn (environment and fill),
// the mirror direction and the roughness, for reflection_inputs.glsl (zero weight under
// ROUGH_SPECULAR: no lookup to replace).
// gBounced: the pixel's radiance as the bake's light transport re-emits it, diffusely with the
// bounce albedo (the diffuse albedo plus a metal's lobe), what a reflection of it shows.
vec3 gLobeWeight = vec3(0.0), gLobeDrawn = vec3(0.0), gMirror = vec3(0.0, 0.0, 1.0), gBounced = vec3(0.0);
float gRoughness = 1.0;
vec3 materialRadiance(vec3 x, vec3 normal, vec3 e, float visibility, vec3 fill, vec3 dxW, vec3 dyW) {
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
  vec2 ab = dfgAt(s, nv);
  vec3 lobe = splitSumWeight(s, ab);
#ifdef ROUGH_SPECULAR
  spec += lobe * (e * s.occlusion * 0.31830988618379067);
#else
  float a = s.roughness * s.roughness;
  // The lobe's visible share reflects the environment; the rest the surroundings that hide it,
  // taken at their mean radiance, `fill` (the walls of a room).
  float so = specularOcclusion(nv, visibility * s.occlusion, a);
  gLobeDrawn = lobe * (so * reflectedEnvironment(s, v) + (1.0 - so) * s.occlusion * fill);
  spec += gLobeDrawn;
  gLobeWeight = lobe * s.occlusion;
  gMirror = reflect(-v, s.n);
  gRoughness = s.roughness;
#endif
  gBounced = (s.diffuse + metalLobeWeight(s, ab)) * diffuseE * 0.31830988618379067 + s.emission;
  return s.diffuse * diffuseE * 0.31830988618379067 + spec + s.emission;
}
