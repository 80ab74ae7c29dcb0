// probe_weights.glsl, per corner C of the cell (C is replaced by 0..7): its weight.
  {  // corner C
    vec3 f = anyTrilinear ? lerp[C] : max(lerp[C], vec3(kTrilinearFloor));
    vec3 d = x - pv[C].xyz;
    weight[C] = f.x * f.y * f.z * pv[C].w * leakWeight(probe[C], d, length(d), n);
    sum += weight[C];
  }
