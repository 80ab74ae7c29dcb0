// The variants of the baked and receiver shaders (private header of render/): one bit per
// feature a material or a frame may need, compiled in by #defines after the #version line, so
// that a shader runs no branch and interpolates no varying for a feature it lacks.
#pragma once

#include <string>

namespace prt::render {

/// Material variant of a shader: bit kVariantTexture (base colour texture sampled), bit
/// kVariantColor (COLOR_0 present), bit kVariantMask (alphaMode MASK: cutouts discarded), bit
/// kVariantBlend (alphaMode BLEND: the alpha is the fragment's opacity), bit kVariantTwoSided (a
/// baked double-sided instance with back-side transfer: each fragment is shaded with the side
/// it is seen from), bit kVariantDirect (direct lights lit per pixel with shadow maps:
/// direct_shading.h), bit kVariantTransmission (KHR_materials_transmission's texture sampled:
/// the opacity is 1 − factor × its R), bit kVariantFullMaterial (MaterialShading::Full: the glTF
/// metallic-roughness material, material_pass.cpp), bit kVariantMaterialTextures (the material
/// has a metallic-roughness, normal, occlusion or emissive texture: MATERIAL programs read the
/// slots; without it they read none, as llvmpipe pays for a texture lookup behind a uniform
/// branch not taken), bit kVariantRoughSpecular (a material without a metallic-roughness texture
/// whose roughness is at least kRoughSpecularRoughness: its lobe reflects the diffuse light's
/// surroundings, e/π, instead of the prefiltered environment; material_radiance.glsl).
constexpr int kVariantTexture = 1, kVariantColor = 2, kVariantMask = 4, kVariantBlend = 8, kVariantTwoSided = 16,
              kVariantDirect = 32, kVariantTransmission = 64, kVariantFullMaterial = 128,
              kVariantMaterialTextures = 256, kVariantRoughSpecular = 512, kVariants = 1024;
/// The roughness from which a material's environment specular is its diffuse light's e/π (at
/// roughness 1 the split sum's prefiltered lobe is the cosine lobe: docs/render.md, "Materials").
constexpr float kRoughSpecularRoughness = 0.9f;
/// The bits a shadow caster's material needs (the cutout depth programs).
constexpr int kVariantMaterialBits =
    kVariantTexture | kVariantColor | kVariantMask | kVariantBlend | kVariantTransmission;

/// `source` (starting with its #version line) with HAS_TEXTURE / HAS_COLOR / HAS_MASK /
/// HAS_BLEND / TWO_SIDED / DIRECT / HAS_TRANSMISSION_TEXTURE / MATERIAL / MATERIAL_TEXTURES /
/// ROUGH_SPECULAR (and
/// HAS_TEXCOORD where a
/// texture may be sampled) defined after that line as `variant` says.
std::string withMaterialDefines(const std::string& source, int variant);

}  // namespace prt::render
