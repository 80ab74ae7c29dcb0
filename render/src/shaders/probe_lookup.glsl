// The receivers' probe lookup (probe_shading.cpp): the grid's buffers and uniforms, then
// @PROBE_WEIGHTS@ (probe_weights.glsl) and @INCIDENT_RADIANCE@, incidentRadiance(x, n, T)
// unrolled over the @TEXELS@ packed texels.
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
@INCIDENT_RADIANCE@
