// glTF materials and their textures: base colour (metallic-roughness or
// KHR_materials_pbrSpecularGlossiness), KHR_texture_transform, alpha and
// KHR_materials_transmission (the other metallic-roughness fields: gltf_material_pbr.cpp).
// Images are kept encoded at load time; only the textures of materials the default scene uses
// are decoded here, PNG/JPEG with stb and WebP with libwebp, and those only shading reads
// (normal, occlusion, emissive, specular) only on request, so a bake of a scene full of normal
// maps does not pay for them. Part of the glTF reader (gltf_reader.h).
#include <stb_image.h>

#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <glm/gtc/type_ptr.hpp>

#include "gltf_reader.h"
#include "image_webp.h"
#include "prt/error.h"

namespace prt::gltf {

namespace {

// Limits on hostile input, checked before anything that scales with them is allocated
// (docs/robustness.md; the file size and JSON nesting limits are in uri_guard.h and uri_guard.cpp).
// Base colour textures are decoded to float RGBA (16 bytes a texel): at most 1 GiB, and no
// side beyond what GPUs load (16384).
constexpr int64_t kMaxTextureSide = 16384;
constexpr int64_t kMaxTexels = int64_t(1) << 26;

/// The sRGB decoding curve (IEC 61966-2-1), exact. Kept local: the copy in image.h belongs to
/// another part of the library.
double srgbDecode(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

static_assert(Texture::kRepeat == TINYGLTF_TEXTURE_WRAP_REPEAT &&
              Texture::kClampToEdge == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE &&
              Texture::kMirroredRepeat == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT);

bool isWrapMode(int mode) {
  return mode == TINYGLTF_TEXTURE_WRAP_REPEAT || mode == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE ||
         mode == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT;
}

/// Before stb_image sees the bytes: only the formats glTF allows (PNG, JPEG), and dimensions
/// from the header within the limits, so a corrupt header cannot make stb_image allocate.
void checkTextureHeader(const Gltf& g, const std::vector<unsigned char>& bytes, const std::string& where) {
  bool png = bytes.size() >= 8 && std::memcmp(bytes.data(), "\x89PNG\r\n\x1a\n", 8) == 0;
  bool jpeg = bytes.size() >= 3 && std::memcmp(bytes.data(), "\xFF\xD8\xFF", 3) == 0;
  if (!png && !jpeg) fail(g, cat(where, ": not a PNG or JPEG image"));
  int w = 0, h = 0, comp = 0;
  int size = static_cast<int>(std::min<size_t>(bytes.size(), std::numeric_limits<int>::max()));
  if (!stbi_info_from_memory(bytes.data(), size, &w, &h, &comp))
    fail(g, cat(where, ": cannot decode (", stbi_failure_reason(), ")"));
  if (w <= 0 || h <= 0 || w > kMaxTextureSide || h > kMaxTextureSide || int64_t(w) * h > kMaxTexels)
    fail(g, cat(where, ": image ", w, "x", h, " is too large (at most ", kMaxTextureSide, " a side, ", kMaxTexels,
                " texels)"));
}

/// The image a texture shows: EXT_texture_webp's when it names one (prt decodes WebP, and
/// `source` is then a PNG/JPEG fallback or absent), else `source`.
int textureSource(const tinygltf::Texture& t) {
  auto ext = t.extensions.find(kTextureWebp);
  if (ext == t.extensions.end() || !ext->second.IsObject() || !ext->second.Has("source")) return t.source;
  const tinygltf::Value& source = ext->second.Get("source");
  return source.IsInt() ? source.Get<int>() : -1;
}

/// Decodes glTF texture `index` into linear RGBA: as sRGB base colour, or (`srgb` false) as
/// data whose texels are linear already (a transmission texture).
Texture decodeBaseColorTexture(const Gltf& g, int index, bool srgb = true) {
  const tinygltf::Model& m = g.model;
  const tinygltf::Texture& t = m.textures[size_t(index)];
  std::string where = cat("texture ", index);
  const int source = textureSource(t);
  if (source < 0 || size_t(source) >= m.images.size()) fail(g, cat(where, ": image ", source, " does not exist"));
  const tinygltf::Image& image = m.images[size_t(source)];
  where = cat(where, " / image ", source, image.uri.empty() ? "" : cat(" ('", image.uri, "')"));
  if (image.image.empty()) fail(g, cat(where, ": could not be read"));
  Texture out;
  out.name = !t.name.empty() ? t.name : !image.name.empty() ? image.name : image.uri;
  if (t.sampler >= 0) {
    if (size_t(t.sampler) >= m.samplers.size()) fail(g, cat(where, ": sampler ", t.sampler, " does not exist"));
    const tinygltf::Sampler& s = m.samplers[size_t(t.sampler)];
    if (!isWrapMode(s.wrapS) || !isWrapMode(s.wrapT))
      fail(g, cat("sampler ", t.sampler, ": unknown wrap mode ", isWrapMode(s.wrapS) ? s.wrapT : s.wrapS));
    out.wrapS = s.wrapS;
    out.wrapT = s.wrapT;
  }
  const auto* bytes = image.image.data();
  int size = static_cast<int>(std::min<size_t>(image.image.size(), std::numeric_limits<int>::max()));
  int w = 0, h = 0, comp = 0;
  bool wide = false;
  void* pixels = nullptr;
  Rgba8 webp;  // EXT_texture_webp, decoded by libwebp (image_webp.h)
  if (isWebp(image.image)) {
    std::string error;
    webp = decodeWebp(image.image, kMaxTextureSide, kMaxTexels, error);
    if (!error.empty()) fail(g, cat(where, ": ", error));
    w = webp.width;
    h = webp.height;
    pixels = webp.texels.data();
  } else {
    checkTextureHeader(g, image.image, where);
    wide = stbi_is_16_bit_from_memory(bytes, size);
    pixels = wide ? static_cast<void*>(stbi_load_16_from_memory(bytes, size, &w, &h, &comp, 4))
                  : static_cast<void*>(stbi_load_from_memory(bytes, size, &w, &h, &comp, 4));
    if (!pixels) fail(g, cat(where, ": cannot decode (", stbi_failure_reason(), ")"));
  }
  out.width = w;
  out.height = h;
  out.texels.resize(size_t(w) * size_t(h));
  std::array<float, 256> lut8;
  for (int i = 0; i < 256; ++i) lut8[size_t(i)] = static_cast<float>(srgbDecode(i / 255.0));
  if (!wide) {  // Texture::sample reads the bytes: the same values as the floats below, exactly
    out.texels8.resize(out.texels.size());
    const auto* b = static_cast<const unsigned char*>(pixels);
    for (size_t i = 0; i < out.texels8.size(); ++i)
      out.texels8[i] = uint32_t(b[4 * i]) | uint32_t(b[4 * i + 1]) << 8 | uint32_t(b[4 * i + 2]) << 16 |
                       uint32_t(b[4 * i + 3]) << 24;
    for (int i = 0; i < 256; ++i) {
      out.levels8[0][size_t(i)] = srgb ? lut8[size_t(i)] : i / 255.0f;
      out.levels8[1][size_t(i)] = i / 255.0f;
    }
  }
  for (size_t i = 0; i < out.texels.size(); ++i) {
    for (int c = 0; c < 4; ++c) {
      float v;
      if (wide) {
        double x = static_cast<const uint16_t*>(pixels)[4 * i + size_t(c)] / 65535.0;
        v = static_cast<float>(c < 3 && srgb ? srgbDecode(x) : x);  // alpha is linear
      } else {
        unsigned char x = static_cast<const unsigned char*>(pixels)[4 * i + size_t(c)];
        v = c < 3 && srgb ? lut8[x] : x / 255.0f;
      }
      out.texels[i][c] = v;
    }
  }
  if (webp.texels.empty()) stbi_image_free(pixels);
  return out;
}

bool specGlossOf(const tinygltf::Material& src) {
  auto it = src.extensions.find(kSpecularGlossiness);
  return it != src.extensions.end() && it->second.IsObject();
}

/// A number array of `size` values (glTF JSON held by tinygltf), checked as it is read.
std::vector<double> numbers(const Gltf& g, const tinygltf::Value& v, size_t size, const std::string& where) {
  if (!v.IsArray() || v.ArrayLen() != size) fail(g, cat(where, ": expected an array of ", size, " numbers"));
  std::vector<double> out;
  for (size_t i = 0; i < size; ++i) {
    const tinygltf::Value& x = v.Get(int(i));
    if (!x.IsNumber() || !std::isfinite(x.GetNumberAsDouble()))
      fail(g, cat(where, ": value ", i, " is not a finite number"));
    out.push_back(x.GetNumberAsDouble());
  }
  return out;
}

/// alphaMode, alphaCutoff and KHR_materials_transmission. The transmission texture is read at
/// the base colour's texture coordinates (MeshInstance holds one set): one that names another
/// TEXCOORD_n or another KHR_texture_transform is ignored with a warning (the factor stays),
/// unless the material has no base colour texture, whose coordinates it then decides.
void readAlphaAndTransmission(const Gltf& g, const tinygltf::Material& src, const std::string& where, Material& mat,
                              BaseColorSource& source, std::vector<std::string>& warnings) {
  if (src.alphaMode == "MASK")
    mat.alphaMode = Material::AlphaMode::Mask;
  else if (src.alphaMode == "BLEND")
    mat.alphaMode = Material::AlphaMode::Blend;
  else if (!src.alphaMode.empty() && src.alphaMode != "OPAQUE")
    fail(g, cat(where, ": alphaMode '", src.alphaMode, "' is not OPAQUE, MASK or BLEND"));
  if (!std::isfinite(src.alphaCutoff) || src.alphaCutoff < 0.0)
    fail(g, cat(where, ": alphaCutoff ", src.alphaCutoff, " is not a non-negative number"));
  mat.alphaCutoff = static_cast<float>(src.alphaCutoff);
  auto ext = src.extensions.find(kTransmission);
  if (ext == src.extensions.end() || !ext->second.IsObject()) return;
  const tinygltf::Value& t = ext->second;
  const std::string here = cat(where, " / ", kTransmission);
  if (t.Has("transmissionFactor")) {
    const tinygltf::Value& f = t.Get("transmissionFactor");
    if (!f.IsNumber() || !std::isfinite(f.GetNumberAsDouble()) || f.GetNumberAsDouble() < 0.0 ||
        f.GetNumberAsDouble() > 1.0)
      fail(g, cat(here, " / transmissionFactor: not a number in [0, 1]"));
    mat.transmissionFactor = static_cast<float>(f.GetNumberAsDouble());
  }
  if (!t.Has("transmissionTexture")) return;
  const tinygltf::Value& info = t.Get("transmissionTexture");
  const tinygltf::Value& index = info.Get("index");
  if (!info.IsObject() || !index.IsInt() || index.Get<int>() < 0 || size_t(index.Get<int>()) >= g.model.textures.size())
    fail(g, cat(here, " / transmissionTexture: expected an object with the index of a texture"));
  BaseColorSource own;
  const tinygltf::Value& texCoord = info.Get("texCoord");
  if (texCoord.IsInt()) own.texCoord = texCoord.Get<int>();
  const tinygltf::Value& extensions = info.Get("extensions");
  if (extensions.IsObject())
    readTextureTransform(g, extensions.Get<tinygltf::Value::Object>(), cat(here, " / transmissionTexture"), own);
  if (source.texture < 0) {
    source.texCoord = own.texCoord;
    source.uvTransform = own.uvTransform;
  } else if (own.texCoord != source.texCoord || own.uvTransform != source.uvTransform) {
    warnings.push_back(cat(g.path, ": ", here,
                           ": transmissionTexture uses other texture coordinates than the base "
                           "colour texture; ignored (transmissionFactor only)"));
    return;
  }
  source.transmissionTexture = index.Get<int>();
}

}  // namespace

// KHR_texture_transform as the affine map uv -> T·R·S·uv of its specification (rotation
/// counter-clockwise in the image, whose v points down: u' = u cos r + v sin r,
/// v' = -u sin r + v cos r), and its texCoord override if it has one.
void readTextureTransform(const Gltf& g, const tinygltf::ExtensionMap& extensions, const std::string& where,
                          BaseColorSource& out) {
  auto it = extensions.find(kTextureTransform);
  if (it == extensions.end() || !it->second.IsObject()) return;
  const tinygltf::Value& t = it->second;
  const std::string here = cat(where, " / ", kTextureTransform);
  glm::dvec2 offset(0.0), scale(1.0);
  double rotation = 0.0;
  if (t.Has("offset")) offset = glm::make_vec2(numbers(g, t.Get("offset"), 2, cat(here, " / offset")).data());
  if (t.Has("scale")) scale = glm::make_vec2(numbers(g, t.Get("scale"), 2, cat(here, " / scale")).data());
  if (t.Has("rotation")) {
    const tinygltf::Value& r = t.Get("rotation");
    if (!r.IsNumber() || !std::isfinite(r.GetNumberAsDouble())) fail(g, cat(here, " / rotation: not a finite number"));
    rotation = r.GetNumberAsDouble();
  }
  if (t.Has("texCoord")) {
    const tinygltf::Value& c = t.Get("texCoord");
    if (!c.IsInt() || c.Get<int>() < 0) fail(g, cat(here, " / texCoord: not a non-negative integer"));
    out.texCoord = c.Get<int>();
  }
  const double c = std::cos(rotation), s = std::sin(rotation);
  const glm::dmat3 translate(1, 0, 0, 0, 1, 0, offset.x, offset.y, 1);  // glm is column-major
  const glm::dmat3 rotate(c, -s, 0, s, c, 0, 0, 0, 1);
  const glm::dmat3 scaling(scale.x, 0, 0, 0, scale.y, 0, 0, 0, 1);
  out.uvTransform = translate * rotate * scaling;
}

std::string materialWhere(const Gltf& g, size_t index) {
  const std::string& name = g.model.materials[index].name;
  return name.empty() ? cat("material ", index) : cat("material ", index, " '", name, "'");
}

std::vector<BaseColorSource> readMaterials(const Gltf& g, Scene& scene) {
  const tinygltf::Model& m = g.model;
  std::vector<BaseColorSource> sources;
  for (size_t i = 0; i < m.materials.size(); ++i) {
    const tinygltf::Material& src = m.materials[i];
    const std::string where = cat("material ", i);
    Material mat;
    mat.name = src.name;
    mat.specularGlossiness = specGlossOf(src);
    BaseColorSource source;
    int texture = -1;
    auto specGloss = src.extensions.find(kSpecularGlossiness);
    if (mat.specularGlossiness) {
      // The extension replaces the metallic-roughness model: its diffuse colour is the albedo.
      const tinygltf::Value& sg = specGloss->second;
      const std::string here = cat(where, " / ", kSpecularGlossiness);
      if (sg.Has("diffuseFactor"))
        mat.baseColorFactor =
            glm::vec4(glm::make_vec4(numbers(g, sg.Get("diffuseFactor"), 4, cat(here, " / diffuseFactor")).data()));
      if (sg.Has("diffuseTexture")) {
        const tinygltf::Value& info = sg.Get("diffuseTexture");
        const tinygltf::Value& index = info.Get("index");
        if (!info.IsObject() || !index.IsInt())
          fail(g, cat(here, " / diffuseTexture: expected an object with an integer index"));
        texture = index.Get<int>();
        const tinygltf::Value& texCoord = info.Get("texCoord");
        if (texCoord.IsInt()) source.texCoord = texCoord.Get<int>();
        const tinygltf::Value& ext = info.Get("extensions");
        if (ext.IsObject())
          readTextureTransform(g, ext.Get<tinygltf::Value::Object>(), cat(here, " / diffuseTexture"), source);
      }
    } else {
      const std::vector<double>& f = src.pbrMetallicRoughness.baseColorFactor;
      if (f.size() == 4)
        mat.baseColorFactor = glm::vec4(f[0], f[1], f[2], f[3]);
      else if (!f.empty())
        fail(g, cat(where, ": baseColorFactor has ", f.size(), " values, expected 4"));
      const tinygltf::TextureInfo& info = src.pbrMetallicRoughness.baseColorTexture;
      texture = info.index;
      source.texCoord = info.texCoord;
      readTextureTransform(g, info.extensions, cat(where, " / baseColorTexture"), source);
    }
    if (!std::isfinite(glm::dot(mat.baseColorFactor, mat.baseColorFactor)))  // as floats
      fail(g, cat(where, ": baseColorFactor is not finite"));
    if (texture >= 0 && size_t(texture) >= m.textures.size())
      fail(g, cat(where, ": base colour texture ", texture, " does not exist"));
    source.texture = texture;
    readAlphaAndTransmission(g, src, where, mat, source, scene.warnings);
    mat.baseColorTexCoord = source.texCoord;
    mat.doubleSided = src.doubleSided;
    mat.unlit = src.extensions.count(kUnlit) > 0;
    // The extension replaces the metallic-roughness model: its fields keep their defaults.
    if (!mat.specularGlossiness) readPbrFields(g, i, mat, source, scene.warnings);
    scene.materials.push_back(mat);
    sources.push_back(source);
  }
  return sources;
}

void decodeUsedTextures(const Gltf& g, const std::vector<BaseColorSource>& sources, bool shadingTextures,
                        Scene& scene) {
  std::vector<char> used(scene.materials.size(), 0);
  for (const MeshInstance& inst : scene.meshes)
    if (inst.material >= 0) used[size_t(inst.material)] = 1;
  std::map<std::pair<int, bool>, int> slot;  // (glTF texture, sRGB) -> Scene::textures
  auto decode = [&](int texture, bool srgb) {
    auto [it, fresh] = slot.emplace(std::make_pair(texture, srgb), int(scene.textures.size()));
    if (fresh) scene.textures.push_back(decodeBaseColorTexture(g, texture, srgb));  // may throw: the caller erases
    return it->second;
  };
  for (size_t i = 0; i < sources.size(); ++i) {
    if (!used[i]) continue;
    if (sources[i].texture >= 0) scene.materials[i].baseColorTexture = decode(sources[i].texture, true);
    if (sources[i].transmissionTexture >= 0)
      scene.materials[i].transmissionTexture = decode(sources[i].transmissionTexture, false);
    // A texture past the base colour that cannot be read leaves its factor alone, as a viewer
    // would draw the material: a warning, not a refused file (prt read none of them before).
    for (const BaseColorSource::Extra& e : sources[i].extras) {
      if (!shadingTextures && e.shadingOnly) continue;
      try {
        (scene.materials[i].*e.slot).texture = decode(e.texture, e.srgb);
      } catch (const Error& error) {
        slot.erase(std::make_pair(e.texture, e.srgb));
        scene.warnings.push_back(cat(error.what(), " (", materialWhere(g, i), "); the texture is ignored"));
      }
    }
  }
}

}  // namespace prt::gltf
