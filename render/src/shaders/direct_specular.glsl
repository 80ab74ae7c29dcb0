// The direct lights on a MATERIAL pixel (needs direct_lighting.glsl and material_shading.glsl):
// their irradiance at the shading normal, as directIrradiance, and their GGX highlight, both
// times the shadow maps' visible share. A disk's highlight is taken at a representative point
// (Karis 2013, "Area lights"): the direction of its cap closest to the reflected view ray, with
// the lobe's energy renormalised by (α/α')², α' = min(1, α + tan r / 2), so that a wide light
// does not add the energy of a whole lobe at each of its points. The lights inside the scene
// likewise (below).
void directShading(vec3 x, vec3 ng, Surface s, vec3 v, vec3 dxW, vec3 dyW, out vec3 e, out vec3 spec) {
  e = vec3(0.0);
  spec = vec3(0.0);
  float a = s.roughness * s.roughness;
  vec3 r = reflect(-v, s.n);
  int k = 0;
  do {
    vec4 dir = uDirectDir[k];
    float cotR = uDirectIrradiance[k].w;
    float f = directCosineFactor(s.n, dir, cotR);
    // The cap above the geometric horizon too (a normal map may turn n away from it): a test,
    // not a second cosine factor, which would cost as much as the highlight.
    bool facing = f > 0.0 || dot(ng, dir.xyz) > -sqrt(dir.w);
    float vis = 1.0;
    if (uShadowed != 0) vis = visibleShare(k, x, ng, facing, dxW, dyW);
    vec3 l = dir.xyz;
    float norm = 1.0;
    if (dir.w > 0.0) {
      float sinR = sqrt(dir.w), cosR = sqrt(max(1.0 - dir.w, 0.0));
      float c = dot(r, dir.xyz);
      vec3 off = r - c * dir.xyz;
      l = c >= cosR ? r : (dot(off, off) > 1e-12 ? cosR * dir.xyz + sinR * normalize(off) : dir.xyz);
      float a2 = min(1.0, a + 0.5 * sinR / max(cosR, 1e-6));
      norm = (a / a2) * (a / a2);
    }
    vec3 E = k < uDirectCount ? uDirectIrradiance[k].rgb * vis : vec3(0.0);
    e += E * f;
    spec += E * (f * norm) * specularBrdf(s, l, v, a);
    k += uLoopStep;
  } while (k < uDirectCount);
  // The lights inside the scene: their irradiance at n and their GGX highlight. A point or spot
  // light's from its centre, exactly; an area light's at a representative point as above: the
  // point of the sphere of its radius about its centre (a sphere light's own; a disk's radius, a
  // rectangle's half diagonal: an approximation that ignores their shape) closest to the
  // reflected ray, the lobe renormalised by (α/α')², α' = min(1, α + tan r / 2), r the sphere's
  // angular radius from x.
  for (int j = 0; j < uLocalCount; ++j) {
    vec3 E = localUnoccluded(j, x, s.n);
    if (max(E.r, max(E.g, E.b)) <= 0.0) continue;
    if (uLocalShadowed != 0) E *= localVisibleShare(j, x, ng);
    e += E;
    vec3 d = uLocalPos[j].xyz - x;
    float dist = max(length(d), 1e-6);
    vec3 l = d / dist;
    float norm = 1.0, R = uLocalPos[j].w > 1.5 ? uLocalShape[j].z : 0.0;
    if (R > 0.0 && dist > R) {
      vec3 toRay = dot(d, r) * r - d;  // from the centre to the reflected ray's nearest point
      float gap = length(toRay);
      l = normalize(d + toRay * (gap > R ? R / gap : 1.0));
      float sinR = R / dist, cosR = sqrt(max(1.0 - sinR * sinR, 0.0));
      float a2 = min(1.0, a + 0.5 * sinR / max(cosR, 1e-6));
      norm = (a / a2) * (a / a2);
    }
    spec += E * norm * specularBrdf(s, l, v, a);
  }
}
