// The glTF 2.0 metallic-roughness material past its base colour: metallic and roughness
// factors and texture, normal, occlusion and emissive textures, KHR_materials_emissive_strength,
// KHR_materials_ior and KHR_materials_specular. Defaults are the specification's; a value out of
// its range is replaced (clamped, or the default where it is not a finite number) with a
// warning naming the material and the value used instead, as a viewer would still draw the
// file. Part of the glTF reader (gltf_reader.h).
#include <cmath>
#include <string>
#include <vector>

#include "gltf_reader.h"
#include "prt/error.h"

namespace prt::gltf {

namespace {

/// What one material's fields are checked against, and where the warnings go.
struct FieldChecker {
  const Gltf& g;
  std::string where;  // "material 3 'Hull'"
  std::vector<std::string>& warnings;

  /// `value` (read as a double) in [lo, hi]: clamped into it, or `fallback` where not finite.
  float range(double value, double lo, double hi, float fallback, const std::string& field) const {
    if (!std::isfinite(value)) {
      warnings.push_back(cat(g.path, ": ", where, ": ", field, " is not a finite number; ", fallback, " used"));
      return fallback;
    }
    if (value < lo || value > hi) {
      const double used = value < lo ? lo : hi;
      warnings.push_back(
          cat(g.path, ": ", where, ": ", field, " ", value, " is outside [", lo, ", ", hi, "]; ", used, " used"));
      return static_cast<float>(used);
    }
    return static_cast<float>(value);
  }
  /// An extension's number field: its value checked by range(), `fallback` where absent, and
  /// where not a number (with a warning).
  float number(const tinygltf::Value& object, const char* key, double lo, double hi, float fallback,
               const std::string& field) const {
    return object.Has(key) ? value(object.Get(key), lo, hi, fallback, field) : fallback;
  }
  /// One JSON value that should be a number in [lo, hi].
  float value(const tinygltf::Value& v, double lo, double hi, float fallback, const std::string& field) const {
    if (!v.IsNumber()) {
      warnings.push_back(cat(g.path, ": ", where, ": ", field, " is not a number; ", fallback, " used"));
      return fallback;
    }
    return range(v.GetNumberAsDouble(), lo, hi, fallback, field);
  }
};

/// The coordinate set of a texture reference with TEXCOORD_n `texCoord` and `extensions`
/// (KHR_texture_transform): 0 where it reads what the base colour reads, else a set of
/// source.moreUvSets, shared with an earlier slot that reads the same.
int uvSetOf(const Gltf& g, int texCoord, const tinygltf::ExtensionMap& extensions, const std::string& where,
            BaseColorSource& source) {
  BaseColorSource own;
  own.texCoord = texCoord;
  readTextureTransform(g, extensions, where, own);
  if (own.texCoord == source.texCoord && own.uvTransform == source.uvTransform) {
    source.extrasReadSet0 = true;
    return 0;
  }
  for (size_t k = 0; k < source.moreUvSets.size(); ++k)
    if (source.moreUvSets[k].texCoord == own.texCoord && source.moreUvSets[k].uvTransform == own.uvTransform)
      return int(k + 1);
  source.moreUvSets.push_back({own.texCoord, own.uvTransform});
  return int(source.moreUvSets.size());
}

/// A texture reference of the core material (TextureInfo and its kin): the slot's
/// coordinates, and its texture queued for decoding. A reference to a texture that does not
/// exist is refused, as the base colour's is.
void addSlot(const Gltf& g, const FieldChecker& check, int index, int texCoord,
             const tinygltf::ExtensionMap& extensions, const char* field, bool srgb, bool shadingOnly,
             TextureSlot Material::*slot, Material& mat, BaseColorSource& source) {
  if (index < 0) return;
  if (size_t(index) >= g.model.textures.size()) fail(g, cat(check.where, ": ", field, " ", index, " does not exist"));
  if (texCoord < 0) fail(g, cat(check.where, ": ", field, ": texCoord ", texCoord, " is negative"));
  (mat.*slot).uvSet = uvSetOf(g, texCoord, extensions, cat(check.where, " / ", field), source);
  BaseColorSource probe;
  probe.texCoord = texCoord;
  readTextureTransform(g, extensions, cat(check.where, " / ", field), probe);
  (mat.*slot).texCoord = probe.texCoord;
  source.extras.push_back({index, srgb, shadingOnly, slot});
}

/// The same for a texture reference held as extension JSON ({"index", "texCoord", "extensions"}).
void addExtensionSlot(const Gltf& g, const FieldChecker& check, const tinygltf::Value& object, const char* key,
                      bool srgb, TextureSlot Material::*slot, Material& mat, BaseColorSource& source) {
  if (!object.Has(key)) return;
  const tinygltf::Value& info = object.Get(key);
  const tinygltf::Value& index = info.Get("index");
  if (!info.IsObject() || !index.IsInt())
    fail(g, cat(check.where, ": ", key, ": expected an object with an integer index"));
  const tinygltf::Value& texCoord = info.Get("texCoord");
  const tinygltf::Value& extensions = info.Get("extensions");
  const tinygltf::ExtensionMap none;
  addSlot(g, check, index.Get<int>(), texCoord.IsInt() ? texCoord.Get<int>() : 0,
          extensions.IsObject() ? extensions.Get<tinygltf::Value::Object>() : none, key, srgb, true, slot, mat, source);
}

/// The object of material extension `name`, or null where the material does not have it.
const tinygltf::Value* extension(const tinygltf::Material& src, const char* name) {
  auto it = src.extensions.find(name);
  return it != src.extensions.end() && it->second.IsObject() ? &it->second : nullptr;
}

void readExtensions(const Gltf& g, const tinygltf::Material& src, const FieldChecker& check, Material& mat,
                    BaseColorSource& source) {
  if (const tinygltf::Value* e = extension(src, kEmissiveStrength))
    mat.emissiveStrength = check.number(*e, "emissiveStrength", 0.0, HUGE_VAL, 1.0f, "emissiveStrength");
  if (const tinygltf::Value* e = extension(src, kIor)) {
    // KHR_materials_ior: ior ≥ 1, or exactly 0 (F0 = 1, for converted specular-glossiness).
    mat.ior = check.number(*e, "ior", 0.0, HUGE_VAL, 1.5f, "ior");
    if (mat.ior > 0.0f && mat.ior < 1.0f) {
      check.warnings.push_back(cat(g.path, ": ", check.where, ": ior ", mat.ior,
                                   " is between 0 and 1 (allowed: 0 or at least 1); 1.5 used"));
      mat.ior = 1.5f;
    }
  }
  if (const tinygltf::Value* e = extension(src, kSpecular)) {
    mat.specularFactor = check.number(*e, "specularFactor", 0.0, 1.0, 1.0f, "specularFactor");
    if (e->Has("specularColorFactor")) {
      const tinygltf::Value& c = e->Get("specularColorFactor");
      if (!c.IsArray() || c.ArrayLen() != 3) {
        check.warnings.push_back(
            cat(g.path, ": ", check.where, ": specularColorFactor is not an array of 3 numbers; [1, 1, 1] used"));
      } else {
        for (int k = 0; k < 3; ++k)
          mat.specularColorFactor[k] = check.value(c.Get(k), 0.0, HUGE_VAL, 1.0f, cat("specularColorFactor[", k, "]"));
      }
    }
    addExtensionSlot(g, check, *e, "specularTexture", false, &Material::specularTexture, mat, source);
    addExtensionSlot(g, check, *e, "specularColorTexture", true, &Material::specularColorTexture, mat, source);
  }
}

}  // namespace

void readPbrFields(const Gltf& g, size_t index, Material& mat, BaseColorSource& source,
                   std::vector<std::string>& warnings) {
  const tinygltf::Material& src = g.model.materials[index];
  const FieldChecker check{g, materialWhere(g, index), warnings};
  const tinygltf::PbrMetallicRoughness& pbr = src.pbrMetallicRoughness;
  mat.metallicFactor = check.range(pbr.metallicFactor, 0.0, 1.0, 1.0f, "metallicFactor");
  mat.roughnessFactor = check.range(pbr.roughnessFactor, 0.0, 1.0, 1.0f, "roughnessFactor");
  const tinygltf::TextureInfo& mr = pbr.metallicRoughnessTexture;
  addSlot(g, check, mr.index, mr.texCoord, mr.extensions, "metallicRoughnessTexture", false, false,
          &Material::metallicRoughnessTexture, mat, source);
  const tinygltf::NormalTextureInfo& normal = src.normalTexture;
  addSlot(g, check, normal.index, normal.texCoord, normal.extensions, "normalTexture", false, true,
          &Material::normalTexture, mat, source);
  if (normal.index >= 0) {
    mat.normalScale = check.range(normal.scale, -HUGE_VAL, HUGE_VAL, 1.0f, "normalTexture.scale");
    source.normalUvSet = mat.normalTexture.uvSet;
  }
  const tinygltf::OcclusionTextureInfo& occlusion = src.occlusionTexture;
  addSlot(g, check, occlusion.index, occlusion.texCoord, occlusion.extensions, "occlusionTexture", false, true,
          &Material::occlusionTexture, mat, source);
  if (occlusion.index >= 0)
    mat.occlusionStrength = check.range(occlusion.strength, 0.0, 1.0, 1.0f, "occlusionTexture.strength");
  const std::vector<double>& e = src.emissiveFactor;
  if (e.size() == 3) {
    for (int k = 0; k < 3; ++k)
      mat.emissiveFactor[k] = check.range(e[size_t(k)], 0.0, 1.0, 0.0f, cat("emissiveFactor[", k, "]"));
  } else if (!e.empty()) {
    warnings.push_back(cat(g.path, ": ", check.where, ": emissiveFactor has ", e.size(), " values; [0, 0, 0] used"));
  }
  const tinygltf::TextureInfo& emissive = src.emissiveTexture;
  addSlot(g, check, emissive.index, emissive.texCoord, emissive.extensions, "emissiveTexture", true, true,
          &Material::emissiveTexture, mat, source);
  readExtensions(g, src, check, mat, source);
}

}  // namespace prt::gltf
