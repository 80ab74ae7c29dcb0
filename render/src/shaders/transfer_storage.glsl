// baked_vertex.glsl's @TRANSFER@ for more bands: the transfer from a storage buffer,
// vertex-major ((v·n² + i)·3 + c), indexed by gl_VertexID. Opens main().
const int kCoeffs = @COEFFS@;
layout(std430, binding = 0) readonly buffer Transfer { float transfer[]; };
uniform vec3 uLight[kCoeffs];
void main() {
  uint base = uint(gl_VertexID) * uint(kCoeffs * 3);
  vec3 e = vec3(0.0);
  for (int i = 0; i < kCoeffs; ++i) {
    uint k = base + uint(i * 3);
    e += vec3(transfer[k], transfer[k + 1u], transfer[k + 2u]) * uLight[i];
  }
  vTransferLight = e;
#ifdef TWO_SIDED
  vec3 eb = vec3(0.0);
  for (int i = 0; i < kCoeffs; ++i) {
    uint k = base + uint(i * 3);
    eb += vec3(transferBack[k], transferBack[k + 1u], transferBack[k + 2u]) * uLight[i];
  }
  vTransferLightBack = eb;
#endif
