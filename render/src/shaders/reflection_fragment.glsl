// Screen-space reflections (reflection_pass.cpp; docs/render.md, "Materials"). A glossy MATERIAL
// pixel (reflection_inputs.glsl: lobe weight W > 0) reflected S = W·(so · environment +
// (1 − so) · fill), its specular occlusion so splitting the lobe between the map and the
// surroundings' mean radiance. Here a march along the mirror direction r through the depth
// buffer looks for the surface r meets; where it finds one on the screen, that surface's radiance
// as the bake's transport re-emits it (diffusely, with the bounce albedo: location 4 of
// reflection_inputs.glsl), averaged over the lobe's footprint (a mip level), is what the lobe
// reflects: the pass adds (W · L_hit − S) · fade (additive blending), fade going to 0 within 5%
// of the screen's border. Where r leaves the screen or meets nothing the pixel keeps S.
#version 450 core
layout(binding = 0) uniform sampler2D uDepth;
layout(binding = 1) uniform sampler2D uWeight;  // rgb: W; a: roughness
layout(binding = 2) uniform sampler2D uDrawn;  // rgb: S
layout(binding = 3) uniform sampler2D uMirror;
layout(binding = 4) uniform sampler2D uBounced;  // rgb: the surfaces' bounced radiance; a: 1 on them; mipmapped
uniform mat4 uViewProj;
uniform mat4 uInvViewProj;
uniform vec2 uViewport;
uniform float uMaxDistance;    // world units the march covers at most: the scene's diagonal
uniform float uPerspective;    // 1: perspective (w_clip = view depth), 0: orthographic
uniform float uPixelsPerUnit;  // pixels per world unit at w_clip = 1 (viewport height / 2 · P[1][1])
uniform int uSteps;            // samples along the segment on the screen, at most
out vec4 fragColor;

vec3 worldAt(vec2 uv, float depth) {
  vec4 p = uInvViewProj * vec4(uv * 2.0 - 1.0, depth, 1.0);
  return p.xyz / p.w;
}

void main() {
  ivec2 pix = ivec2(gl_FragCoord.xy);
  vec4 w = texelFetch(uWeight, pix, 0);
  if (max(w.r, max(w.g, w.b)) <= 0.0) discard;
  float d0 = texelFetch(uDepth, pix, 0).r;
  vec2 uv0 = (vec2(pix) + 0.5) / uViewport;
  vec3 x = worldAt(uv0, d0);
  vec3 r = normalize(texelFetch(uMirror, pix, 0).xyz);
  vec4 h0 = uViewProj * vec4(x, 1.0);
  // Under perspective, up to 4 times the point's view depth: farther, what r meets is rarely on
  // the screen, and the march's steps would grow with the scene (a town's 2 km ground).
  float reach = uPerspective > 0.5 ? min(uMaxDistance, 4.0 * h0.w) : uMaxDistance;
  vec4 h1 = uViewProj * vec4(x + r * reach, 1.0);
  // Keep the segment in front of the camera: w_clip = view depth under perspective.
  float wMin = 0.01 * h0.w;
  if (h1.w < wMin) h1 = mix(h0, h1, (h0.w - wMin) / (h0.w - h1.w));
  vec3 p0 = h0.xyz / h0.w, p1 = h1.xyz / h1.w;  // NDC x, y and depth: affine along the screen line
  vec2 s0 = p0.xy * 0.5 + 0.5, s1 = p1.xy * 0.5 + 0.5;
  // Clip the screen segment to the viewport.
  vec2 ds = s1 - s0;
  float tEnd = 1.0;
  for (int k = 0; k < 2; ++k) {
    if (ds[k] > 0.0) tEnd = min(tEnd, (1.0 - s0[k]) / ds[k]);
    if (ds[k] < 0.0) tEnd = min(tEnd, -s0[k] / ds[k]);
  }
  float pixels = length(ds * uViewport) * tEnd;
  if (pixels < 2.0) discard;
  int steps = int(min(float(uSteps), ceil(pixels)));
  float dt = tEnd / float(steps);
  float t = 2.0 / length(ds * uViewport);  // start two pixels out: not the pixel's own surface
  float tPrev = t;
  bool hit = false;
  for (int i = 0; i < steps && t <= tEnd; ++i) {
    vec2 s = s0 + ds * t;
    float ray = mix(p0.z, p1.z, t);
    float scene = textureLod(uDepth, s, 0.0).r;
    if (ray < scene) {  // reversed depth: the ray has passed behind the surface there
      // Bisect between the last sample in front and this one.
      float a = tPrev, b = t;
      for (int j = 0; j < 6; ++j) {
        float m = 0.5 * (a + b);
        if (mix(p0.z, p1.z, m) < textureLod(uDepth, s0 + ds * m, 0.0).r)
          b = m;
        else
          a = m;
      }
      t = b;
      hit = true;
      break;
    }
    tPrev = t;
    t += dt;
  }
  if (!hit) discard;
  vec2 sh = s0 + ds * t;
  float sceneDepth = textureLod(uDepth, sh, 0.0).r;
  if (sceneDepth <= 0.0) discard;  // the background (cleared far depth)
  // After the bisection the ray is within a 64th of a step of a surface it crossed; a surface
  // farther from it than 3% of the way (or that 64th) is one the ray passed behind at its
  // silhouette, not one it met.
  vec3 xs = worldAt(sh, sceneDepth), xr = worldAt(sh, mix(p0.z, p1.z, t));
  float along = distance(x, xr);
  float stepWorld = along * dt / max(t, 1e-6);
  if (distance(xs, xr) > max(stepWorld / 32.0, 0.03 * along)) discard;
  // The surface there must face the ray: its normal from the depth of the next pixels, turned
  // towards the camera; a ray reaching it from behind (one that slipped behind a ridge) is no hit.
  vec2 px = 1.0 / uViewport;
  vec2 sa = sh + vec2(px.x, 0.0), sb = sh + vec2(0.0, px.y);
  vec3 nh = cross(worldAt(sa, textureLod(uDepth, sa, 0.0).r) - xs, worldAt(sb, textureLod(uDepth, sb, 0.0).r) - xs);
  if (dot(nh, worldAt(sh, 1.0) - xs) < 0.0) nh = -nh;
  if (dot(nh, r) >= 0.0) discard;
  // The lobe's footprint at the hit, d away: a box 5α·d wide (α = roughness²). Half of GGX's
  // reflected rays lie within 2α of r, and a box 5α wide holds the disc of radius 2α's share.
  float alpha = w.a * w.a;
  float wHit = max((uViewProj * vec4(xs, 1.0)).w, 1e-6);
  float radius = min(5.0 * alpha, 1.0) * distance(x, xs) * uPixelsPerUnit / wHit;
  vec4 bounced = textureLod(uBounced, sh, log2(max(radius, 1.0)));
  if (bounced.a <= 0.0) discard;
  vec3 L = bounced.rgb / bounced.a;  // the mean over the footprint's surfaces, not the empty pixels
  vec2 edge = min(sh, 1.0 - sh);
  float fade = smoothstep(0.0, 0.05, edge.x) * smoothstep(0.0, 0.05, edge.y);
  vec3 drawn = texelFetch(uDrawn, pix, 0).rgb;
  fragColor = vec4((w.rgb * L - drawn) * fade, 0.0);
}
