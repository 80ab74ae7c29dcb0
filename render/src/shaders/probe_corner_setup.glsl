// probe_weights.glsl, per corner C of the cell (C is replaced by 0..7): its probe and trilinear factor.
  {  // corner C
    ivec3 off = ivec3(C & 1, (C >> 1) & 1, (C >> 2) & 1);
    int p = findProbe(base + off);
    pv[C] = texelFetch(uProbeStatic, p * kStaticTexels);
    bool valid = pv[C].w > 0.0;  // invalid probes are never read
    probe[C] = valid ? p : 0;
    pv[C].w = valid ? pv[C].w : 0.0;
    lerp[C] = vec3(off.x != 0 ? t.x : 1.0 - t.x, off.y != 0 ? t.y : 1.0 - t.y, off.z != 0 ? t.z : 1.0 - t.z);
    anyTrilinear = anyTrilinear || (valid && lerp[C].x * lerp[C].y * lerp[C].z > 0.0);
  }
