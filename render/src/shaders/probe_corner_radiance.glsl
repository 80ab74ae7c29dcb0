// probe_lookup.glsl, per corner C of the cell (C is replaced by 0..7): the corner's packed texels
// weighted by w[C] and added to T (@TEXEL_SUMS@, one line per texel).
  {  // corner C
    int base = probe[C] * kTexels;
@TEXEL_SUMS@
  }
