// The fragment stage's material: albedo() = baseColorFactor × baseColorTexture(texcoord) ×
// COLOR_0, and coverage(), which discards a MASK cutout and returns the opacity (alpha × (1 −
// transmission)). Texcoords and colours are read only in the variants compiled with HAS_TEXTURE
// / HAS_COLOR (shader_variants.h): a material without them interpolates no varyings for them and
// runs no branch. Inputs are `centroid`: with multisampling, a pixel on an edge is shaded at its
// covered samples' centroid instead of its centre, which may lie outside the triangle.
#ifdef HAS_TEXCOORD
centroid in vec2 vTexcoord;
#endif
#ifdef HAS_TEXTURE
layout(binding = 0) uniform sampler2D uBaseColorTexture;
#endif
#ifdef HAS_TRANSMISSION_TEXTURE
layout(binding = 6) uniform sampler2D uTransmissionTexture;  // KHR_materials_transmission, R
#endif
#ifdef HAS_COLOR
centroid in vec4 vColor;
#endif
uniform vec4 uBaseColor;
// baseColorFactor × baseColorTexture(texcoord) × COLOR_0, RGBA: albedo() is its RGB, baseAlpha()
// its alpha (each lane the same product as on its own).
vec4 baseColor() {
  vec4 c = uBaseColor;
#ifdef HAS_COLOR
  c *= vColor;
#endif
#ifdef HAS_TEXTURE
  c *= texture(uBaseColorTexture, vTexcoord);
#endif
  return c;
}
vec3 albedo() { return baseColor().rgb; }
float baseAlpha() { return baseColor().a; }
#ifdef HAS_MASK
uniform float uAlphaCutoff;
#endif
uniform float uOpacity;  // 1 − transmissionFactor
// 1 − transmission: transmissionFactor × the transmission texture's R where it has one.
float opacity() {
#ifdef HAS_TRANSMISSION_TEXTURE
  return 1.0 - (1.0 - uOpacity) * clamp(texture(uTransmissionTexture, vTexcoord).r, 0.0, 1.0);
#else
  return uOpacity;
#endif
}
// The fragment's opacity, the alpha it is blended with; a MASK cutout is discarded here.
float coverage() {
#ifdef HAS_MASK
  if (baseAlpha() < uAlphaCutoff) discard;
#endif
#ifdef HAS_BLEND
  return clamp(baseAlpha(), 0.0, 1.0) * opacity();
#else
  return opacity();
#endif
}
