// The receivers' probe lookup (probe_shading.cpp): the grid's buffers and uniforms, then
// @PROBE_WEIGHTS@ (probe_weights.glsl) and incidentRadiance(x, n, T) = Σ_p w_p c_p / Σ_p w_p in
// the packed radiance layout (T[i] = texel i), or the light in that layout where no probe
// applies. Its sums are unrolled over the @TEXELS@ packed texels: @TEXELS_CLEARED@ sets each to
// zero, @CORNER_SUMS@ adds each corner's weighted texels (probe_corner_radiance.glsl) and
// @TEXELS_NORMALISED@ divides by Σ w once, blending into the light beyond the domain (fade > 0,
// as receiverRadiance does).
layout(binding = 1) uniform isamplerBuffer uLattice;       // lattice point -> probe + 1, 0 none
layout(binding = 2) uniform samplerBuffer uProbeStatic;    // kStaticTexels per probe, probe 0 null
layout(binding = 3) uniform samplerBuffer uProbeRadiance;  // c_p packed: packRadiance()
uniform vec3 uOrigin;
uniform vec3 uSpacing;
uniform ivec3 uDims;
uniform float uNearZero;
const int kStaticTexels = @STATIC_TEXELS@;
const int kTexels = @TEXELS@;
// The light itself, packed as the probes are: incident radiance where no probe applies.
uniform vec4 uLightPacked[kTexels];
@PROBE_WEIGHTS@

void incidentRadiance(vec3 x, vec3 n, out vec4 T[kTexels]) {
  int probe[8];
  float w[8];
  float fade;
  float sum = probeWeights(x, n, probe, w, fade);
@TEXELS_CLEARED@
@CORNER_SUMS@
@TEXELS_NORMALISED@
}
