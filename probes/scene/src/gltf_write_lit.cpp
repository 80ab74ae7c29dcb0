// writeLitScene: a relit scene as a glTF file that any viewer shows as it is. Each baked
// instance carries its exitant radiance twice: exact, as _RADIANCE (linear, unclamped: what
// tools read), and display-ready, as COLOR_0 (the radiance clamped to 0..1, the range glTF
// gives COLOR_0), on unlit white materials.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "gltf_write.h"
#include "prt/scene.h"

namespace prt {

using namespace gltf;

namespace {

/// The front side's radiance, unclamped; COLOR_0 holds it clamped (kBackRadiance: the back's).
constexpr const char* kRadiance = "_RADIANCE";

/// COLOR_0 for `radiance`: each channel clamped to 0..1, as glTF requires of COLOR_0 (a viewer
/// shows it times the unlit white material); a NaN channel shows as 0.
std::vector<glm::vec3> displayColors(const std::vector<glm::vec3>& radiance) {
  std::vector<glm::vec3> colors(radiance.size());
  for (size_t v = 0; v < radiance.size(); ++v)
    for (int c = 0; c < 3; ++c) colors[v][c] = std::fmin(std::fmax(radiance[v][c], 0.0f), 1.0f);
  return colors;
}

/// Adds each lit instance's attributes: _RADIANCE, COLOR_0 and, where given, the back side's
/// radiance (kBackRadiance).
void addRadianceAttributes(tinygltf::Model& m, int& staging, const Scene& scene,
                           const std::vector<std::vector<glm::vec3>>& radiance,
                           const std::vector<std::vector<glm::vec3>>* backRadiance) {
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    if (radiance[k].empty()) continue;
    PRT_CHECK_EQ(radiance[k].size(), scene.meshes[k].vertexCount());
    tinygltf::Primitive& prim = primitiveOf(m, scene.meshes[k]);
    prim.attributes[kRadiance] = addVec3Accessor(m, staging, radiance[k], "radiance");
    prim.attributes["COLOR_0"] = addVec3Accessor(m, staging, displayColors(radiance[k]), "radiance clamped to 0..1");
    if (!backRadiance || (*backRadiance)[k].empty()) continue;
    PRT_CHECK_EQ((*backRadiance)[k].size(), scene.meshes[k].vertexCount());
    prim.attributes[kBackRadiance] = addVec3Accessor(m, staging, (*backRadiance)[k], "back radiance");
  }
}

/// Every material becomes unlit white, so a viewer shows COLOR_0 as it is.
void makeMaterialsUnlitWhite(tinygltf::Model& m) {
  auto unlitWhite = [](const std::string& name, bool doubleSided) {
    tinygltf::Material mat;
    mat.name = name;
    mat.doubleSided = doubleSided;
    mat.pbrMetallicRoughness.baseColorFactor = {1.0, 1.0, 1.0, 1.0};
    mat.pbrMetallicRoughness.metallicFactor = 0.0;  // the fallback the unlit spec suggests
    mat.pbrMetallicRoughness.roughnessFactor = 0.9;
    mat.extensions[kUnlit] = tinygltf::Value(tinygltf::Value::Object{});
    return mat;
  };
  for (tinygltf::Material& mat : m.materials) mat = unlitWhite(mat.name, mat.doubleSided);
  int fallback = -1;  // for primitives on the glTF default material, which is lit
  for (tinygltf::Mesh& mesh : m.meshes) {
    for (tinygltf::Primitive& prim : mesh.primitives) {
      if (prim.material >= 0) continue;
      if (fallback < 0) {
        m.materials.push_back(unlitWhite("prt unlit", false));
        fallback = static_cast<int>(m.materials.size() - 1);
      }
      prim.material = fallback;
    }
  }
  m.textures.clear();
  m.images.clear();
  m.samplers.clear();
  // Material and texture extensions have nothing left to apply to.
  auto gone = [](const std::string& e) {
    return (e.rfind("KHR_materials_", 0) == 0 && e != kUnlit) || e == kTextureTransform || e == "KHR_texture_basisu" ||
           e == "EXT_texture_webp";
  };
  std::erase_if(m.extensionsUsed, gone);
  std::erase_if(m.extensionsRequired, gone);
  addExtensionUsed(m, kUnlit);
}

/// Removes meshes without primitives (glTF requires at least one) and the nodes' references.
void removeEmptyMeshes(tinygltf::Model& m) {
  std::vector<int> to(m.meshes.size(), -1);
  std::vector<tinygltf::Mesh> kept;
  for (size_t i = 0; i < m.meshes.size(); ++i) {
    if (m.meshes[i].primitives.empty()) continue;
    to[i] = static_cast<int>(kept.size());
    kept.push_back(std::move(m.meshes[i]));
  }
  m.meshes = std::move(kept);
  for (tinygltf::Node& n : m.nodes)
    if (n.mesh >= 0) n.mesh = size_t(n.mesh) < to.size() ? to[size_t(n.mesh)] : -1;
}

/// Removes the primitives of instances without radiance; a node left without primitives
/// loses its mesh.
void removeUnlitInstances(tinygltf::Model& m, const Scene& scene, const std::vector<std::vector<glm::vec3>>& radiance) {
  std::map<int, std::set<int>> drop;  // node -> primitives
  for (size_t k = 0; k < scene.meshes.size(); ++k)
    if (radiance[k].empty()) drop[scene.meshes[k].node].insert(scene.meshes[k].primitive);
  for (const auto& [node, prims] : drop) {
    auto& list = m.meshes[size_t(m.nodes[size_t(node)].mesh)].primitives;
    for (auto it = prims.rbegin(); it != prims.rend(); ++it) list.erase(list.begin() + *it);
  }
  removeEmptyMeshes(m);
}

/// Texture coordinates and tangents serve textures (tangents only normal textures), and the
/// lit file has no textures left: TEXCOORD_n and TANGENT go, from the primitives and their
/// morph targets (the Khronos glTF Validator would report them unused).
void dropTextureAttributes(tinygltf::Model& m) {
  auto servesTextures = [](const auto& attribute) {
    return attribute.first.rfind("TEXCOORD_", 0) == 0 || attribute.first == "TANGENT";
  };
  for (tinygltf::Mesh& mesh : m.meshes)
    for (tinygltf::Primitive& prim : mesh.primitives) {
      std::erase_if(prim.attributes, servesTextures);
      for (auto& target : prim.targets) std::erase_if(target, servesTextures);
    }
}

}  // namespace

void writeLitScene(const std::string& inputPath, const Scene& scene,
                   const std::vector<std::vector<glm::vec3>>& radiance, const std::string& outPath,
                   const std::vector<std::vector<glm::vec3>>* backRadiance) {
  PRT_CHECK_EQ(radiance.size(), scene.meshes.size());
  int staging = -1;
  // reloadForWriting drops the _PRT_SH_* attributes: a lit file is for looking at, and the
  // transfer would make it bands² × 12 bytes per vertex larger. writeSceneFile then leaves
  // their data out.
  Gltf g = reloadForWriting(inputPath, scene, staging);
  addRadianceAttributes(g.model, staging, scene, radiance, backRadiance);
  removeUnlitInstances(g.model, scene, radiance);
  makeMaterialsUnlitWhite(g.model);
  dropTextureAttributes(g.model);
  writeSceneFile(g, g.model, staging, outPath);
}

}  // namespace prt
