// baked_vertex.glsl's @TRANSFER@ for bands <= kMaxAttributeBands: the flat transfer read as
// @CHUNKS@ vec4 attributes (@CHUNK_INPUTS@), chunk k summed into accumulator k mod 3
// (@CHUNK_SUMS@), whose lanes hold (r g b r), (g b r g), (b r g b). Opens main().
@CHUNK_INPUTS@
uniform vec4 uLightFlat[@CHUNKS@];
void main() {
  vec4 a[3] = vec4[3](vec4(0.0), vec4(0.0), vec4(0.0));
@CHUNK_SUMS@
  vTransferLight = vec3(a[0].x + a[0].w + a[1].z + a[2].y,
                        a[0].y + a[1].x + a[1].w + a[2].z,
                        a[0].z + a[1].y + a[2].x + a[2].w);
#ifdef TWO_SIDED
  uint baseBack = uint(gl_VertexID) * uint(kCoeffsAll * 3);
  vec3 eb = vec3(0.0);
  for (int f = 0; f < kCoeffsAll * 3; ++f) eb[f % 3] += transferBack[baseBack + uint(f)] * uLightFlat[f >> 2][f & 3];
  vTransferLightBack = eb;
#endif
