// The vertex stage's side of albedo_inputs.glsl: the declarations.
#ifdef HAS_TEXCOORD
out vec2 vTexcoord;
#endif
#ifdef HAS_COLOR
out vec4 vColor;
#endif
