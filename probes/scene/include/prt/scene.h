// The scene model: what prt reads from glTF 2.0 (.gltf / .glb) and writes back.
//
// A Scene is flat and in world space: one MeshInstance per (node, primitive) pair of the
// default scene (a mesh used by two nodes gives two instances); meshes no node of it uses are
// ignored. Vertices of an instance are the primitive's vertices one to one (same order, same
// count), so vertex i of an instance is vertex i of the glTF primitive and per-vertex transfer
// can be written back as attributes; the one exception is a primitive without NORMAL, whose
// flat normals split the vertices shared by faces of different orientation
// (MeshInstance::fileVertex), and whose split geometry the baked file then holds; the other is
// a mesh refined by the bake (MeshInstance::fileBlend), whose refined geometry the baked file
// holds. Triangle
// strips and fans become triangle lists; zero-area triangles are dropped (one warning per
// primitive, their vertices kept); points and lines are skipped with a warning.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "prt/animation.h"
#include "prt/bake_record.h"
#include "prt/bounce_operator.h"
#include "prt/error.h"
#include "prt/sh.h"

namespace prt {

/// A texture decoded to linear RGBA (sRGB-decoded when it holds base colour).
struct Texture {
  std::string name;
  int width = 0;
  int height = 0;
  std::vector<glm::vec4> texels;  // row-major, row 0 = top of the image (v = 0)
  /// The 8-bit texels `texels` were decoded from (RGBA, R in the low byte), when the image had 8
  /// bits a channel: texels[i][c] == levels8[c < 3 ? 0 : 1][byte c of texels8[i]], exactly.
  /// sample() reads these (a quarter of the bytes, the same values); empty otherwise.
  std::vector<uint32_t> texels8;
  std::array<std::array<float, 256>, 2> levels8{};  // [0]: the colour channels' decode, [1]: alpha's
  /// glTF sampler wrap modes, as the file stores them.
  static constexpr int kRepeat = 10497, kClampToEdge = 33071, kMirroredRepeat = 33648;
  int wrapS = kRepeat;
  int wrapT = kRepeat;
  /// Bilinear lookup at glTF texture coordinates (u right, v down), honouring the wrap modes.
  glm::vec4 sample(const glm::vec2& uv) const;
};

/// A texture a material reads other than the base colour: the decoded texture and the
/// coordinates it is read at. Its KHR_texture_transform is applied to the instance's
/// coordinate set `uvSet` (MeshInstance::uvs), shared by the slots of one material that read
/// the same TEXCOORD_n through the same transform.
struct TextureSlot {
  int texture = -1;  // index into Scene::textures, -1 if none (or not decoded: LoadOptions::shadingTextures)
  int texCoord = 0;  // which TEXCOORD_n (after the transform's override)
  int uvSet = 0;     // MeshInstance::uvs(uvSet); 0 is MeshInstance::texcoords, the base colour's
};

/// The base colour is pbrMetallicRoughness's, or KHR_materials_pbrSpecularGlossiness's
/// diffuse colour where the material has that extension (the extension replaces the
/// metallic-roughness model). Its texture's KHR_texture_transform is already applied to
/// MeshInstance::texcoords. The other fields are the glTF 2.0 metallic-roughness material with
/// the specification's defaults (metallicFactor 1 where absent); values out of their range are
/// replaced with a warning naming the material (Scene::warnings). The textures' texel values
/// are linear except baseColor, emissive and specularColor (sRGB-decoded).
struct Material {
  std::string name;
  glm::vec4 baseColorFactor{1.0f};  // linear
  int baseColorTexture = -1;        // index into Scene::textures, -1 if none
  int baseColorTexCoord = 0;        // which TEXCOORD_n the texture uses (after the transform's override)
  bool doubleSided = false;
  bool unlit = false;               // KHR_materials_unlit
  bool specularGlossiness = false;  // KHR_materials_pbrSpecularGlossiness (the fields below keep their defaults)
  /// glTF alphaMode. The alpha is baseColorFactor.a × texture alpha × COLOR_0 alpha (alphaAt).
  /// Opaque: alpha ignored; Mask: a cutout, solid where alpha >= alphaCutoff, absent elsewhere;
  /// Blend: a partial occluder of opacity alpha (docs/formats.md, "Materials as light sees them").
  enum class AlphaMode { Opaque, Mask, Blend };
  AlphaMode alphaMode = AlphaMode::Opaque;
  float alphaCutoff = 0.5f;  // Mask only
  /// KHR_materials_transmission: the share of light that goes through (thin and untinted in
  /// prt), transmissionFactor × transmissionTexture's R channel (linear texels).
  float transmissionFactor = 0.0f;
  int transmissionTexture = -1;  // index into Scene::textures (decoded linear), -1 if none

  // pbrMetallicRoughness: metallic = metallicFactor × texture B, roughness = roughnessFactor × texture G.
  float metallicFactor = 1.0f;   // [0, 1]
  float roughnessFactor = 1.0f;  // [0, 1], perceptual (α = roughness²)
  TextureSlot metallicRoughnessTexture;
  TextureSlot normalTexture;  // tangent-space normals; MeshInstance::tangents where present
  float normalScale = 1.0f;   // scales the texture's X and Y
  TextureSlot occlusionTexture;
  float occlusionStrength = 1.0f;  // [0, 1]: 1 + strength × (texture R − 1)
  glm::vec3 emissiveFactor{0.0f};  // linear, [0, 1] each
  TextureSlot emissiveTexture;
  float emissiveStrength = 1.0f;  // KHR_materials_emissive_strength, ≥ 0
  float ior = 1.5f;               // KHR_materials_ior: 0 (F0 = 1) or ≥ 1
  // KHR_materials_specular: the dielectric's specular weight and F0 colour.
  float specularFactor = 1.0f;          // [0, 1], × specularTexture's A
  glm::vec3 specularColorFactor{1.0f};  // ≥ 0, × specularColorTexture's RGB
  TextureSlot specularTexture;
  TextureSlot specularColorTexture;
};

/// Why an instance is a receiver: left out of the bake (neither baked nor an occluder) and lit
/// per pixel from the probe grid by the renderer. An explicit mark comes before Animated; the
/// topmost marked ancestor gives it, Option before Extras where one node has both.
enum class ReceiverReason {
  None,      // baked (or receiverOnly set by hand, as tests do)
  Option,    // LoadOptions::receiverNodes names the node or an ancestor (prt bake --receiver)
  Extras,    // the node or an ancestor has extras {"prt": {"receiver": true}}
  Animated,  // an animation channel moves the node or an ancestor (docs/render.md, "Animation")
};

/// One glTF primitive placed by one node, in world space.
struct MeshInstance {
  std::string name;       // "node name/mesh name/primitive k", for messages
  int node = -1;          // glTF node index
  int mesh = -1;          // glTF mesh index
  int primitive = -1;     // primitive index within the mesh
  glm::dmat4 world{1.0};  // node's world transform

  std::vector<glm::vec3> positions;  // world space
  std::vector<glm::vec3> normals;    // world space, unit; flat (per face) if the file has none
  /// The base colour texture's TEXCOORD_n (KHR_texture_transform's texCoord if it names one),
  /// with the texture's KHR_texture_transform applied, so a lookup at an interpolated
  /// coordinate is the transformed lookup glTF defines; empty if none.
  std::vector<glm::vec2> texcoords;
  /// The other coordinate sets the material's textures read (TextureSlot::uvSet k ≥ 1 is
  /// moreTexcoords[k − 1]), transformed like texcoords; one left empty where the primitive
  /// lacks its TEXCOORD_n (a warning says so, and the slots reading it use their factors).
  std::vector<std::vector<glm::vec2>> moreTexcoords;
  /// Tangents for the normal map, world space: xyz unit and orthogonal to the normal, w = ±1
  /// the handedness (bitangent = w · normal × tangent.xyz). The file's TANGENT where it has one
  /// (and NORMAL), else generated by MikkTSpace (prt/tangents.h) from the normal texture's
  /// coordinates; empty where the material has no normal texture or the primitive no
  /// coordinates for it.
  std::vector<glm::vec4> tangents;
  std::vector<glm::vec4> colors;  // COLOR_0, linear RGBA; empty if none
  std::vector<uint32_t> indices;  // triangle list, 3 per triangle
  /// Which vertex of the glTF primitive each vertex is: empty when they are one to one. Filled
  /// only for a primitive without NORMAL whose flat normals split vertices: the first copy of
  /// a file vertex keeps its index, the extra copies follow the file's vertices.
  std::vector<uint32_t> fileVertex;
  /// A vertex as a weighted sum of file vertices of one file triangle: Σ weight[j] · file
  /// vertex vertex[j], unused slots of weight 0 (weights sum to 1).
  struct FileBlend {
    uint32_t vertex[3] = {0, 0, 0};
    float weight[3] = {1.0f, 0.0f, 0.0f};
  };
  /// Which file vertices each vertex interpolates: empty unless the bake's adaptive refinement
  /// (prt/bake/refine.h) added vertices, and then used instead of fileVertex. The baked file
  /// holds the refined primitive: every attribute interpolated, the refined triangles.
  std::vector<FileBlend> fileBlend;
  int material = -1;                                     // index into Scene::materials, -1 = glTF default (white)
  bool receiverOnly = false;                             // excluded from the bake (moving / unbaked object)
  ReceiverReason receiverReason = ReceiverReason::None;  // why, as the loader decided

  /// Per-vertex transfer when read from a baked file: vertexCount × bands² RGB, vertex-major,
  /// bands = Scene::transferBands. Empty: the instance is not baked.
  std::vector<glm::vec3> transfer;
  /// The back side's transfer (normal −n, light arriving from behind the surface), same layout:
  /// filled only for an instance of a double-sided material baked by a prt that bakes both
  /// sides (_PRT_SH_BACK_ attributes, docs/formats.md). Empty: one-sided, or an older bake.
  std::vector<glm::vec3> transferBack;
  /// The direct part of `transfer` (bounce 0: t⁰_i = ∫ V y_i max(n·ω, 0) dω, first-hit
  /// visibility), colourless: vertexCount × bands² floats, vertex-major. What a direct light
  /// (a sun) replaces by its exact shadowed irradiance, keeping transfer − direct for its
  /// bounced light (docs/lights.md, "Direct lights"). Empty: baked before prt kept it apart.
  std::vector<float> transferDirect;
  /// The same for the back side (transferBack's direct part); empty when transferBack is.
  std::vector<float> transferDirectBack;

  size_t vertexCount() const { return positions.size(); }
  /// Coordinate set `set` (TextureSlot::uvSet): texcoords for 0, moreTexcoords[set − 1] after;
  /// an empty set where the instance has none.
  const std::vector<glm::vec2>& uvs(int set) const {
    static const std::vector<glm::vec2> kNone;
    if (set == 0) return texcoords;
    return set > 0 && size_t(set) <= moreTexcoords.size() ? moreTexcoords[size_t(set) - 1] : kNone;
  }
  size_t triangleCount() const { return indices.size() / 3; }
  /// The bands² coefficients of `vertex`; `bands` is the scene's (Scene::transferBands).
  const glm::vec3* transferOf(size_t vertex, int bands) const {
    return transfer.data() + vertex * static_cast<size_t>(bands) * static_cast<size_t>(bands);
  }
  bool hasBackTransfer() const { return !transferBack.empty(); }
  bool hasDirectTransfer() const { return !transferDirect.empty(); }
  const float* directTransferOf(size_t vertex, int bands, bool back = false) const {
    return (back ? transferDirectBack : transferDirect).data() +
           vertex * static_cast<size_t>(bands) * static_cast<size_t>(bands);
  }
  const glm::vec3* backTransferOf(size_t vertex, int bands) const {
    return transferBack.data() + vertex * static_cast<size_t>(bands) * static_cast<size_t>(bands);
  }
};

struct Camera {
  std::string name;
  int node = -1;
  glm::dmat4 world{1.0};  // camera looks down its local -Z, +Y up (glTF)
  bool perspective = true;
  double yfov = 0.8;         // radians (perspective)
  double aspectRatio = 0.0;  // 0 = not given (use the image's)
  double znear = 0.01;
  double zfar = 0.0;              // 0 = infinite
  double xmag = 1.0, ymag = 1.0;  // orthographic
};

/// KHR_lights_punctual light, in world space.
struct PunctualLight {
  enum class Type { Directional, Point, Spot };
  std::string name;
  int node = -1;
  Type type = Type::Directional;
  glm::vec3 color{1.0f};
  float intensity = 1.0f;
  float range = 0.0f;  // 0 = infinite
  glm::vec3 position{0.0f};
  glm::vec3 direction{0, 0, -1};  // direction the light travels (world)
  float innerConeAngle = 0.0f, outerConeAngle = 0.7853982f;
};

/// A Scene is its SceneAnimation (nodes and animations) and what the file places with them.
/// Deriving keeps scene.nodes and scene.animations where they were, and lets a Scene stand
/// wherever a SceneAnimation is asked for (isAnimated(scene, node), nodeWorldAt(scene, ...)).
struct Scene : SceneAnimation {
  std::string path;
  std::vector<MeshInstance> meshes;
  std::vector<Material> materials;
  std::vector<Texture> textures;
  std::vector<Camera> cameras;
  std::vector<PunctualLight> lights;
  glm::vec3 boundsMin{0.0f}, boundsMax{0.0f};  // of all instances
  std::vector<std::string> warnings;           // skipped or repaired input, one line each
  std::optional<BakeRecord> bakeRecord;        // asset.extras.prt of a baked file, validated
  /// The direct-to-indirect operator of a baked file (asset.extras.prt_operator, checked
  /// against the scene), or of a bake about to be written; null when there is none.
  std::shared_ptr<const BounceOperator> bounceOperator;
  /// The band count of every instance's transfer: the _PRT_SH_ attributes', or, in a bake
  /// whose every instance is a receiver (no attributes), the record's. 0: not baked.
  int transferBands = 0;
  bool allowExternalUris = false;  // loaded with LoadOptions::allowExternalUris (writers reread so)
};

struct LoadOptions {
  /// Node names (or indices as decimal strings) whose subtrees are receivers only. Nodes whose
  /// extras hold {"prt": {"receiver": true}} are receivers too, and so are nodes moved by an
  /// animation channel (on themselves or an ancestor) unless their extras hold
  /// {"prt": {"receiver": false}} (then they are baked in their rest pose, with a warning).
  std::vector<std::string> receiverNodes;
  /// Read buffer and image URIs that point outside the scene's folder (absolute paths, `..`,
  /// symbolic links leading out). Off: such a URI is refused with an error.
  bool allowExternalUris = false;
  /// Also decode the textures that only shading reads (normal, occlusion, emissive, specular,
  /// specular colour). Off: their slots keep the glTF texture's coordinates but no decoded
  /// texture (TextureSlot::texture −1), so a bake does not pay for them; base colour,
  /// transmission and metallic-roughness textures (the bake's albedo reads metalness) are
  /// always decoded. Tangents do not need the decoded normal texture.
  bool shadingTextures = false;
};

/// Loads .gltf or .glb. Throws prt::Error naming the file and the element on bad input:
/// missing or malformed file, non-finite positions, out-of-range indices, unsupported required
/// extensions (named), a scene with no triangles,
/// malformed animations (accessor types or counts, key times not increasing, NaN values),
/// URIs outside the scene's folder (unless allowed), limits in docs/robustness.md.
Scene loadScene(const std::string& path, const LoadOptions& options = {});
/// What loadScene throws for a buffer or image URI outside the scene's folder while
/// LoadOptions::allowExternalUris is off (a tool adds the option that allows it).
class ExternalUriRefused : public Error {
 public:
  using Error::Error;
};
/// Loads .gltf or .glb bytes held in memory; `name` stands for the file in messages and its
/// extension picks the format when the bytes lack the GLB magic. URIs may only be data: URIs
/// (there is no folder). Same checks and errors as loadScene.
Scene loadSceneFromMemory(const std::string& name, const std::string& bytes, const LoadOptions& options = {});

/// One line per receiver node (in the order of Scene::meshes, each node once) saying why it is
/// one, e.g. "node 5 'Ball': extras.prt.receiver, animated (translation of node 2 'Arm')".
/// `receiverOption` names LoadOptions::receiverNodes in these lines (a tool passes its option).
std::vector<std::string> describeReceivers(const Scene& scene,
                                           const std::string& receiverOption = "LoadOptions::receiverNodes");

/// The albedo the bake's bounces use (docs/bake.md, "Materials"): the diffuse albedo, base
/// colour (linear RGB, baseColorFactor × texture × COLOR_0) × (1 − metallic) × the dielectric's
/// specular share, plus the metal's specular lobe re-emitted diffusely, metallic × (baseColor ·
/// Ā + B̄) with (Ā, B̄) = brdf::cosineAveragedDfg(roughness). metallic = metallicFactor × the
/// metallic-roughness texture's B channel, roughness = roughnessFactor × its G (linear), sampled
/// at its own coordinates as the base colour is at its own. The base colour alone for
/// KHR_materials_pbrSpecularGlossiness, unlit materials and instances without a material. At
/// vertex v.
glm::vec3 albedoAtVertex(const Scene& scene, const MeshInstance& mesh, uint32_t v);
/// The same at a point of triangle `tri` with barycentrics (b1, b2) of its 2nd and 3rd
/// vertices (Embree's u, v).
glm::vec3 albedoAt(const Scene& scene, const MeshInstance& mesh, uint32_t tri, float b1, float b2);
/// The diffuse albedo alone (albedoAtVertex without the metal's specular lobe): what a
/// view-independent radiance ρ E/π (`prt relight`) takes.
glm::vec3 diffuseAlbedoAtVertex(const Scene& scene, const MeshInstance& mesh, uint32_t v);
/// Whether the albedo on `mesh` has a specular part (a metallic-roughness material with
/// metallicFactor > 0): its albedo is then not baseColor × diffuseScale alone.
bool bouncesSpecular(const Scene& scene, const MeshInstance& mesh);
/// The constant part of the diffuse albedo on `mesh`: (1 − metallicFactor) × dielectricScale,
/// or dielectricScale alone where albedoAt reads the metallic-roughness texture (whose B
/// channel then scales metallicFactor point by point); 1 for the cases albedoAt leaves as base
/// colour. dielectricScale = min(1, w / w₀), w = brdf::dielectricDiffuseWeight of the
/// material's ior and specular, w₀ the default dielectric's: 1 unless the material's specular
/// is stronger than the default's.
float diffuseScale(const Scene& scene, const MeshInstance& mesh);
/// Whether albedoAt reads the material's metallic-roughness texture on `mesh`: the texture is
/// decoded and the instance has its coordinates.
bool readsMetallicTexture(const Scene& scene, const MeshInstance& mesh);
/// Base colour alpha (baseColorFactor.a × texture alpha × COLOR_0 alpha) at a point of `tri`.
float alphaAt(const Scene& scene, const MeshInstance& mesh, uint32_t tri, float b1, float b2);
/// Opacity at a point of `tri`: the share of light the surface stops there, in [0, 1]. The
/// coverage (Opaque 1, Mask alpha >= alphaCutoff ? 1 : 0, Blend alpha) × (1 − transmission).
float opacityAt(const Scene& scene, const MeshInstance& mesh, uint32_t tri, float b1, float b2);
/// False when the instance's material makes its opacity 1 everywhere (OPAQUE without
/// transmission, or no material), whatever its alpha.
bool mayPassLight(const Scene& scene, const MeshInstance& mesh);
/// Per instance of the scene: whether its opacity can be below 1 anywhere. Sharper than
/// mayPassLight: a MASK or BLEND instance whose smallest alpha (factor × the texture's smallest
/// texel alpha × the smallest COLOR_0 alpha: interpolation never goes below them) is at least
/// the cutoff (MASK) or 1 (BLEND) is solid too, e.g. MASK over a JPEG. Scans each texture
/// once. The bake tests hits only on these instances.
std::vector<char> passesLight(const Scene& scene);

/// Writes `inputPath`'s scene as .glb with each baked instance's transfer (scene.meshes[k].
/// transfer, scene.transferBands) as attributes _PRT_SH_00 .. (VEC3 float, RGB of coefficient
/// i), the back side's (MeshInstance::transferBack, where filled) as _PRT_SH_BACK_00 .., the
/// direct parts (transferDirect, transferDirectBack, where filled) as _PRT_SH_DIRECT_00 .. and
/// _PRT_SH_BACK_DIRECT_00 .. (SCALAR float), meshes duplicated where one is used by several nodes, strips and fans
/// rewritten as
/// triangle lists, primitives whose vertices were split for flat normals (MeshInstance::
/// fileVertex) rewritten with the split vertices and their NORMAL, primitives refined by the
/// bake (MeshInstance::fileBlend) rewritten with every attribute interpolated and the refined
/// triangles, and `record` (if not null) stored in asset.extras.prt; its bands must be
/// scene.transferBands when the scene holds transfer. Receivers named by
/// LoadOptions::receiverNodes get extras {"prt": {"receiver": true}}, so the file keeps them
/// receivers. Atomic (temp + rename). Both writers write glTF JSON with the buffer as a data:
/// URI where `outPath` ends in .gltf, a .glb otherwise; the files pass the Khronos glTF
/// Validator without errors (a perspective camera's zfar of 0, infinite, is left out).
void writeBakedScene(const std::string& inputPath, const Scene& scene, const BakeRecord* record,
                     const std::string& outPath);

/// Writes the scene (.glb, or .gltf as writeBakedScene does) with per-vertex linear radiance
/// as _RADIANCE (float VEC3, unclamped, the exact values) and as COLOR_0 (float VEC3, each
/// channel clamped to 0..1 as glTF requires), materials replaced by KHR_materials_unlit white
/// so that viewers show COLOR_0 as it is, and TEXCOORD_n and TANGENT left out (no textures
/// remain). radiance[k] holds instance k's vertex values (empty: the instance is left out).
/// backRadiance (if not null), per instance, the back side's values of a double-sided
/// instance, written as _PRT_COLOR_BACK (VEC3 float, unclamped; viewers ignore it and show
/// COLOR_0 on both sides). Lit files older than _RADIANCE hold the unclamped radiance in
/// COLOR_0. Atomic.
void writeLitScene(const std::string& inputPath, const Scene& scene,
                   const std::vector<std::vector<glm::vec3>>& radiance, const std::string& outPath,
                   const std::vector<std::vector<glm::vec3>>* backRadiance = nullptr);

}  // namespace prt
