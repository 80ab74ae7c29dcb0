// The vertex stage's side of albedo_inputs.glsl: the copies, inside main().
#ifdef HAS_TEXCOORD
  vTexcoord = aTexcoord;
#endif
#ifdef HAS_COLOR
  vColor = aColor;
#endif
