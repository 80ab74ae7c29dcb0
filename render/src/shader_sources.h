// The sources of the baked instances', shadow casters', flat and background shaders (private
// header of render/): the GLSL files of render/src/shaders, embedded at build time
// (render_shaders.h), with their @NAME@ values filled in from the C++ constants they share and,
// where the code depends on the band count, the unrolled lines generated here.
#pragma once

#include <initializer_list>
#include <string>
#include <string_view>

#include <GL/glcorearb.h>

namespace prt::render {

/// One @NAME@ placeholder's text.
struct ShaderValue {
  std::string_view name;
  std::string text;
};

/// `source` with each @name@ replaced by its text. A placeholder alone on its line stands for a
/// block: the line goes, and the text (ending with its own line end, or empty) takes its place.
/// Every placeholder must have a value (PRT_CHECK), and every value a placeholder.
std::string fillShader(std::string_view source, std::initializer_list<ShaderValue> values);

// The baked vertex shader reaches a vertex's 3n² transfer floats in one of two ways, chosen by
// band count (measured on llvmpipe, 100k triangles at 256×256, 3 bands: attributes ≈ 15 ms a
// frame, SSBO ≈ 40 ms; llvmpipe fetches attributes in bulk but gathers SSBO loads lane by lane):
// - n <= kMaxAttributeBands: vertex attributes (transfer_attributes.glsl). 3n² <= 48 floats = 12
//   vec4 attributes, which with position, texcoord and colour fits the 16 attributes every GL
//   4.5 offers. The flat float sequence (coefficient i, channel c at 3i + c) is read as vec4
//   chunks; chunk k starts at channel (4k) mod 3, so chunks k ≡ 0, 1, 2 (mod 3) hold (r g b r),
//   (g b r g), (b r g b) and three accumulators sorted by k mod 3 give the channels at the end.
//   The light comes in the same flat layout, zero-padded, so padding contributes nothing.
// - larger n: an SSBO holding the instance's transfer vertex-major ((v·n² + i)·3 + c) indexed by
//   gl_VertexID (glDrawElements without a base vertex makes it the index value); up to 192
//   floats per vertex, beyond any attribute budget (transfer_storage.glsl).
// A double-sided instance with back-side transfer (the TWO_SIDED variant) also computes the back
// side's e from a second SSBO (binding 1, same layout, indexed by gl_VertexID) with the same
// light, whatever the path of the front; the fragment shader picks the side it is seen from by
// gl_FrontFacing (the loader winds every instance counter-clockwise in world space).
// The DIRECT variant (direct lights apart, docs/render.md) subtracts t⁰ · directSh, t⁰ the
// colourless direct part read from an SSBO (binding 2, back side binding 3; n² floats per
// vertex, gl_VertexID), adds the direct lights' gathered bounce (Frame::directBounce; binding 4,
// back side binding 5, RGB per vertex, zero when the bounce goes through directSh), and passes
// the world position and normal (attribute 15) to the fragment shader, which adds the direct
// lights per pixel.
constexpr int kMaxAttributeBands = 4;
constexpr GLuint kNormalAttribute = 15;
constexpr GLuint kFirstTransferAttribute = 3;
constexpr GLuint kTransmissionUnit = 6;  // uTransmissionTexture (albedo_inputs.glsl)
/// vec4 attributes holding 3·bands² transfer floats.
int attributeChunks(int bands);

/// Texture units of the MATERIAL variants: the metallic-roughness, normal, occlusion and
/// emissive textures (material_inputs.glsl), the reflected maps' array, then the DFG table.
constexpr GLuint kMaterialFirstUnit = 13, kEnvironmentFirstUnit = 17;
/// The DFG table's entries a side (material_pass.cpp): bilinear between 32² entries stays within
/// 1% of the integral (test MaterialRender.WhiteFurnaceMetalMatchesMonteCarlo).
constexpr int kDfgSize = 32;
/// material_shading.glsl, its placeholders filled, for `envMaps` reflected maps (compiled in).
std::string materialShadingGlsl(int envMaps);
/// The baked instances' shaders for `bands` bands (to compile through withMaterialDefines).
std::string bakedVertexShader(int bands);
std::string bakedFragmentShader(int envMaps);
/// Shadow casters that let light through (MASK, BLEND, transmission), by material variant.
std::string cutoutDepthVertexShader();
std::string cutoutDepthFragmentShader();
/// Positions only: the raster floor (Shading::Flat) and the opaque shadow casters.
std::string flatVertexShader();
std::string flatFragmentShader();
std::string depthFragmentShader();
/// The background's full-screen triangle and its lookup of RigBackground::radiance.
std::string backgroundVertexShader();
std::string backgroundFragmentShader();
/// The screen-space reflection pass, drawn with the background's triangle.
std::string reflectionFragmentShader();

}  // namespace prt::render
