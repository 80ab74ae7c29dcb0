// What the parts of the glTF reader share (loadScene, gltf_read.cpp). The reader is split by
// role, as Filament's gltfio splits its loader:
//   gltf_read.cpp            parsing the file, assembling the Scene, the public entry points
//   gltf_accessors.cpp       accessors checked against their buffers, indices, triangle lists
//   gltf_primitives.cpp      primitives: degenerate triangles, flat-normal split, normal repair
//   gltf_materials.cpp       materials and the decoding of the base colour textures they use
//   gltf_nodes.cpp           node hierarchy, instances, cameras, lights
//   gltf_animation_read.cpp  animation channels
// Private to prt::scene; it includes tinygltf (through gltf_model.h).
#pragma once

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "gltf_model.h"
#include "prt/scene.h"

namespace prt::gltf {

inline bool allDigits(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); });
}

/// v normalised, or `fallback` where v is zero or not finite.
inline glm::vec3 unitOr(const glm::dvec3& v, const glm::vec3& fallback) {
  double len = glm::length(v);
  return len > 0.0 && std::isfinite(len) ? glm::vec3(v / len) : fallback;
}

// ---------------------------------------------------------------------------------------------
// Accessors (gltf_accessors.cpp; openAccessor, readIndices and toTriangleList are in gltf_model.h)

/// "SCALAR", "VEC2", "VEC3", "VEC4" for a TINYGLTF_TYPE_*, "a matrix type" otherwise.
const char* typeName(int type);
/// Refuses an accessor whose component count is none of `componentCounts`.
void requireType(const Gltf& g, const AccessorData& d, const std::string& where,
                 std::initializer_list<int> componentCounts);
/// Refuses an accessor of another count than the primitive's POSITION count `expected`.
void requireCount(const Gltf& g, const AccessorData& d, const std::string& where, size_t expected);

template <int N>
std::vector<glm::vec<N, float>> readVectors(const AccessorData& d) {
  std::vector<glm::vec<N, float>> out(d.count);
  for (size_t i = 0; i < d.count; ++i)
    for (int c = 0; c < N; ++c) out[i][c] = static_cast<float>(d.get(i, c));
  return out;
}

// ---------------------------------------------------------------------------------------------
// Materials (gltf_materials.cpp)

/// Where a material's base colour comes from: the glTF texture (decoded later, only if an
/// instance uses the material), the TEXCOORD_n it reads and its KHR_texture_transform; and
/// where its other textures come from.
struct BaseColorSource {
  int texture = -1;
  int texCoord = 0;
  glm::dmat3 uvTransform{1.0};
  int transmissionTexture = -1;  // KHR_materials_transmission's, read at the same coordinates
  /// A coordinate set: TEXCOORD_n and the transform applied to it (TextureSlot::uvSet).
  struct UvSet {
    int texCoord = 0;
    glm::dmat3 uvTransform{1.0};
  };
  std::vector<UvSet> moreUvSets;  // uvSet k ≥ 1 at [k − 1]; set 0 is the base colour's above
  /// A texture of another slot: the glTF texture, decoded as sRGB or linear, always or only
  /// with LoadOptions::shadingTextures, into `slot` of the material.
  struct Extra {
    int texture = -1;
    bool srgb = false;
    bool shadingOnly = true;
    TextureSlot Material::*slot = nullptr;
  };
  std::vector<Extra> extras;
  int normalUvSet = -1;         // the normal texture's coordinate set (tangents); -1 without one
  bool extrasReadSet0 = false;  // some other slot reads the base colour's coordinates
};

/// Reads the materials; their base colour textures are decoded later (decodeUsedTextures),
/// once the instances show which materials the default scene uses.
std::vector<BaseColorSource> readMaterials(const Gltf& g, Scene& scene);
/// Decodes the textures of the materials the instances use, each glTF texture once (per
/// colour space), in the order of the materials: a texture only unused meshes need is never
/// read, nor one only shading needs unless `shadingTextures`.
void decodeUsedTextures(const Gltf& g, const std::vector<BaseColorSource>& sources, bool shadingTextures, Scene& scene);

/// KHR_texture_transform of a texture reference, into `out` (texCoord override, uvTransform);
/// nothing where the extension is absent (gltf_materials.cpp).
void readTextureTransform(const Gltf& g, const tinygltf::ExtensionMap& extensions, const std::string& where,
                          BaseColorSource& out);
/// "material 3 'Hull'" (the name where it has one), for messages.
std::string materialWhere(const Gltf& g, size_t index);
/// The metallic-roughness fields past the base colour (gltf_material_pbr.cpp): factors checked
/// (a warning names the material and the value used instead), texture slots with their
/// coordinate sets in `source`, KHR_materials_emissive_strength, _ior and _specular.
void readPbrFields(const Gltf& g, size_t index, Material& mat, BaseColorSource& source,
                   std::vector<std::string>& warnings);

// ---------------------------------------------------------------------------------------------
// Primitives (gltf_primitives.cpp), read once per mesh/primitive, in the primitive's own space

/// A triangle primitive as stored in the file, before any node transform.
struct PrimitiveData {
  bool skipped = true;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;  // empty if absent
  std::vector<glm::vec2> texcoords;
  std::vector<std::vector<glm::vec2>> moreTexcoords;  // BaseColorSource::moreUvSets, transformed
  std::vector<glm::vec4> tangents;                    // TANGENT or generated (MeshInstance::tangents); primitive space
  std::vector<glm::vec4> colors;
  std::vector<uint32_t> indices;     // triangle list, glTF winding, degenerate triangles dropped
  std::vector<uint32_t> fileVertex;  // MeshInstance::fileVertex
  int material = -1;
  int transferBands = 0;
  std::vector<glm::vec3> transfer;
  std::vector<glm::vec3> transferBack;                    // _PRT_SH_BACK_ (double-sided primitives of a bake)
  std::vector<float> transferDirect, transferDirectBack;  // _PRT_SH_DIRECT_, _PRT_SH_BACK_DIRECT_
};

/// Primitive `primIndex` of mesh `meshIndex`: skipped (with a warning) if it has no triangles
/// or no POSITION; else validated, its degenerate triangles dropped and, without NORMAL, its
/// vertices split for flat normals.
PrimitiveData readPrimitive(const Gltf& g, const std::vector<BaseColorSource>& materials, int meshIndex, int primIndex,
                            std::vector<std::string>& warnings);

/// World normals: given ones through the inverse transpose, computed ones where the file has
/// none or a zero (or non-finite) normal. Returns how many given normals were replaced.
size_t setNormals(MeshInstance& inst, const PrimitiveData& p, const glm::dmat3& linear);

// ---------------------------------------------------------------------------------------------
// Nodes (gltf_nodes.cpp)

/// How nodes are marked by the file and the options, before animations are looked at.
struct NodeMarks {
  std::vector<ReceiverReason> receiver;  // Option or Extras where the node itself is marked
  std::vector<char> keepStatic;          // extras {"prt": {"receiver": false}}
};

/// One node of the default scene with its world transform and its inherited marks: a receiver
/// mark on the node or an ancestor makes it a receiver; a static mark keeps an animated node
/// baked (a receiver mark wins over it).
struct NodeVisit {
  int node = -1;
  glm::dmat4 world{1.0};
  ReceiverReason receiver = ReceiverReason::None;
  bool keepStatic = false;
};

/// The receiver and static marks of every node, from extras and from options.receiverNodes.
NodeMarks nodeMarks(const Gltf& g, const LoadOptions& options);
/// The nodes of the default scene, parents before children, each checked (a tree, not too
/// deep, finite transforms).
std::vector<NodeVisit> visitDefaultScene(const Gltf& g, const NodeMarks& marks);
/// Primitive `primIndex` of mesh `meshIndex` placed in the world by the node of `visit`.
MeshInstance makeInstance(const Gltf& g, const NodeVisit& visit, int meshIndex, int primIndex, const PrimitiveData& p,
                          std::vector<std::string>& warnings);
/// The camera a node carries (precondition: it has one).
Camera readCamera(const Gltf& g, const NodeVisit& v);
/// The KHR_lights_punctual light a node carries, if any.
std::optional<PunctualLight> readLight(const Gltf& g, const NodeVisit& v, std::vector<std::string>& warnings);
/// Every node of the file with its parent and rest TRS (or matrix), for animation.
void readNodes(const Gltf& g, Scene& scene);

// ---------------------------------------------------------------------------------------------
// Animations (gltf_animation_read.cpp; the renderer moves receivers with them, the bake is static)

/// Reads every animation, its channels validated.
void readAnimations(const Gltf& g, Scene& scene);
/// Turns every animated instance into a receiver, unless `keepStatic` (per node) keeps it baked.
void makeAnimatedInstancesReceivers(const Gltf& g, Scene& scene, const std::vector<char>& keepStatic);

}  // namespace prt::gltf
