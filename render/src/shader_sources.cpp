// The shaders' sources: embedded GLSL files, their placeholders filled (shader_sources.h).
#include "shader_sources.h"

#include <algorithm>
#include <vector>

#include "direct_shading.h"
#include "environment_prefilter.h"
#include "prt/error.h"
#include "prt/render/renderer.h"
#include "render_shaders.h"
#include "shader_variants.h"

namespace prt::render {

std::string fillShader(std::string_view source, std::initializer_list<ShaderValue> values) {
  std::string out;
  std::vector<bool> used(values.size(), false);
  size_t at = 0;
  for (size_t open = source.find('@'); open != std::string_view::npos; open = source.find('@', at)) {
    const size_t close = source.find('@', open + 1);
    PRT_CHECK(close != std::string_view::npos);
    const std::string_view name = source.substr(open + 1, close - open - 1);
    const auto value = std::find_if(values.begin(), values.end(), [&](const ShaderValue& v) { return v.name == name; });
    PRT_CHECK(value != values.end());  // a placeholder without a value
    used[size_t(value - values.begin())] = true;
    const bool block =
        (open == 0 || source[open - 1] == '\n') && close + 1 < source.size() && source[close + 1] == '\n';
    out.append(source.substr(at, open - at));
    out += value->text;
    at = close + (block ? 2 : 1);
  }
  PRT_CHECK(std::find(used.begin(), used.end(), false) == used.end());  // a value without a placeholder
  out.append(source.substr(at));
  return out;
}

std::string withMaterialDefines(const std::string& source, int variant) {
  const size_t eol = source.find('\n') + 1;
  std::string defines;
  if (variant & kVariantTexture) defines += "#define HAS_TEXTURE 1\n";
  if (variant & kVariantColor) defines += "#define HAS_COLOR 1\n";
  if (variant & kVariantMask) defines += "#define HAS_MASK 1\n";
  if (variant & kVariantBlend) defines += "#define HAS_BLEND 1\n";
  if (variant & kVariantTwoSided) defines += "#define TWO_SIDED 1\n";
  if (variant & kVariantDirect) defines += "#define DIRECT 1\n";
  if (variant & kVariantTransmission) defines += "#define HAS_TRANSMISSION_TEXTURE 1\n";
  if (variant & kVariantFullMaterial) defines += "#define MATERIAL 1\n";
  if (variant & kVariantMaterialTextures) defines += "#define MATERIAL_TEXTURES 1\n";
  if (variant & kVariantRoughSpecular) defines += "#define ROUGH_SPECULAR 1\n";
  if (variant & (kVariantTexture | kVariantTransmission | kVariantFullMaterial)) defines += "#define HAS_TEXCOORD 1\n";
  return source.substr(0, eol) + defines + source.substr(eol);
}

int attributeChunks(int bands) { return (3 * bands * bands + 3) / 4; }

namespace {

// transfer_attributes.glsl for `bands` bands: one input per chunk, and the chunks' sums unrolled.
std::string transferAttributes(int bands) {
  const int chunks = attributeChunks(bands);
  std::string inputs, sums;
  for (int k = 0; k < chunks; ++k) {
    inputs += cat("layout(location = ", kFirstTransferAttribute + k, ") in vec4 aTransfer", k, ";\n");
    sums += cat("  a[", k % 3, "] += aTransfer", k, " * uLightFlat[", k, "];\n");
  }
  return fillShader(shaders::kTransferAttributes,
                    {{"CHUNK_INPUTS", inputs}, {"CHUNKS", cat(chunks)}, {"CHUNK_SUMS", sums}});
}

}  // namespace

std::string bakedVertexShader(int bands) {
  const std::string transfer = bands <= kMaxAttributeBands
                                   ? transferAttributes(bands)
                                   : fillShader(shaders::kTransferStorage, {{"COEFFS", cat(bands * bands)}});
  return fillShader(
      shaders::kBakedVertex,
      {{"COEFFS", cat(bands * bands)}, {"NORMAL_ATTRIBUTE", cat(kNormalAttribute)}, {"TRANSFER", transfer}});
}

std::string materialShadingGlsl(int envMaps) {
  return fillShader(shaders::kMaterialShading, {{"MAX_ENV_MAPS", cat(kMaxReflectedMaps)},
                                                {"ENV_MAPS", cat(envMaps)},
                                                {"DFG_UNIT", cat(kEnvironmentFirstUnit + 1)},
                                                {"LEVELS", cat(kPrefilterLevels)},
                                                {"DFG_SIZE", cat(kDfgSize)}});
}

std::string bakedFragmentShader(int envMaps) {
  return fillShader(shaders::kBakedFragment,
                    {{"DIRECT_LIGHTING", directLightingGlsl()}, {"MATERIAL_SHADING", materialShadingGlsl(envMaps)}});
}

std::string cutoutDepthVertexShader() { return std::string(shaders::kCutoutDepthVertex); }
std::string cutoutDepthFragmentShader() { return std::string(shaders::kCutoutDepthFragment); }
std::string flatVertexShader() { return std::string(shaders::kFlatVertex); }
std::string flatFragmentShader() { return std::string(shaders::kFlatFragment); }
std::string depthFragmentShader() { return std::string(shaders::kDepthFragment); }
std::string backgroundVertexShader() { return std::string(shaders::kBackgroundVertex); }
std::string reflectionFragmentShader() { return std::string(shaders::kReflectionFragment); }

std::string backgroundFragmentShader() {
  return fillShader(shaders::kBackgroundFragment,
                    {{"MAX_MAPS", cat(kMaxBackgroundMaps)}, {"MAX_CAPS", cat(kMaxBackgroundCaps)}});
}

}  // namespace prt::render
