// glTF 2.0 reading (loadScene, loadSceneFromMemory): the file parsed, then the Scene assembled
// from the parts of the reader (gltf_reader.h lists them). The writers are in gltf_write.cpp,
// the URI sandbox in uri_guard.cpp, animation sampling in animation.cpp.
//
// The reader's files are, with gltf_write.cpp, the only files that see tinygltf (through
// gltf_model.h). Reading goes through tinygltf's parser but never trusts it with bounds: every
// accessor is checked against its buffer view and buffer before a byte is read
// (gltf_accessors.cpp). Images are kept encoded at load time (keepEncodedImage) and only the
// base-colour textures of materials the default scene uses are decoded (gltf_materials.cpp),
// so a scene full of normal maps costs nothing and the writers can embed the original
// PNG/JPEG bytes instead of re-encoding them.
#include "prt/scene.h"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "bake_record_json.h"
#include "gltf_decode.h"
#include "gltf_operator.h"
#include "gltf_reader.h"
#include "image_webp.h"
#include "prt/error.h"
#include "uri_guard.h"

namespace prt {

using namespace gltf;

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

// ---------------------------------------------------------------------------------------------
// Small helpers

std::string firstLine(const std::string& text) {
  std::string line = text.substr(0, text.find('\n'));
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
  return line;
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) out.push_back(line);
  return out;
}

Json toJson(const tinygltf::Value& v) {
  if (v.IsBool()) return v.Get<bool>();
  if (v.IsInt()) return v.Get<int>();
  if (v.IsNumber()) return v.GetNumberAsDouble();
  if (v.IsString()) return v.Get<std::string>();
  if (v.IsArray()) {
    Json out = Json::array();
    for (size_t i = 0; i < v.ArrayLen(); ++i) out.push_back(toJson(v.Get(static_cast<int>(i))));
    return out;
  }
  if (v.IsObject()) {
    Json out = Json::object();
    for (const auto& [key, value] : v.Get<tinygltf::Value::Object>()) out[key] = toJson(value);
    return out;
  }
  return nullptr;
}

// ---------------------------------------------------------------------------------------------
// Reading the file

/// tinygltf image callback: keeps the encoded bytes (PNG, JPEG, ...) as they are. Decoding
/// happens later, only for images used as base colour (decodeBaseColorTexture). `model` is
/// the model being parsed: tinygltf 2.7 passes an image's buffer view bytes without checking
/// the view against its buffer, so that is done here, before the bytes are touched.
bool keepEncodedImage(tinygltf::Image* image, const int index, std::string* err, std::string*, int, int,
                      const unsigned char* bytes, int size, void* model) {
  if (image->bufferView >= 0) {
    const auto& m = *static_cast<const tinygltf::Model*>(model);
    const tinygltf::BufferView* view =
        size_t(image->bufferView) < m.bufferViews.size() ? &m.bufferViews[size_t(image->bufferView)] : nullptr;
    bool ok = view && view->buffer >= 0 && size_t(view->buffer) < m.buffers.size() &&
              view->byteOffset <= m.buffers[size_t(view->buffer)].data.size() &&
              view->byteLength <= m.buffers[size_t(view->buffer)].data.size() - view->byteOffset;
    if (!ok) {
      if (err) *err += cat("image ", index, ": buffer view ", image->bufferView, " lies outside its buffer\n");
      return false;
    }
  }
  image->image.assign(bytes, bytes + size);
  image->as_is = true;
  return true;
}

bool looksBinary(const std::string& path, const std::string& bytes) {
  if (bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0) return true;
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".glb";
}

/// The JSON text of a .gltf, or the JSON chunk of a .glb ("" if the container is malformed:
/// tinygltf reports that).
std::string jsonText(const std::string& bytes, bool binary) {
  if (!binary) return bytes;
  if (bytes.size() < 20 || std::memcmp(bytes.data() + 16, "JSON", 4) != 0) return "";
  uint32_t length = 0;
  std::memcpy(&length, bytes.data() + 12, 4);
  return length <= bytes.size() - 20 ? bytes.substr(20, length) : "";
}

/// Parses .gltf or .glb bytes; tinygltf's warnings go to `warnings`, its errors become one
/// prt::Error line. `baseDir` is the folder URIs are relative to ("" = none: from memory).
Gltf parseGltf(const std::string& path, const std::string& bytes, const std::string& baseDir, bool allowExternal,
               std::vector<std::string>* warnings) {
  if (bytes.size() > kMaxFileBytes) throw Error(cat(path, ": larger than ", kMaxFileBytes, " bytes"));
  UriGuard guard;
  guard.baseDir = baseDir;
  guard.allowExternal = allowExternal;
  std::error_code ec;
  if (!baseDir.empty()) guard.canonicalDir = fs::weakly_canonical(baseDir, ec);
  bool binary = looksBinary(path, bytes);
  checkDocument(path, jsonText(bytes, binary), guard);
  // Draco and meshopt data become an ordinary GLB first (gltf_decode.h).
  const std::optional<std::string> decoded = decodeCompressed(path, bytes, binary, guard);
  const std::string& input = decoded ? *decoded : bytes;
  binary = binary || decoded.has_value();
  Gltf g;
  g.path = path;
  tinygltf::TinyGLTF parser;
  parser.SetImageLoader(&keepEncodedImage, &g.model);
  parser.SetFsCallbacks(
      tinygltf::FsCallbacks{&guardedFileExists, &guardedExpandFilePath, &guardedReadWholeFile, &refuseWrite, &guard});
  std::string err, warn;
  bool ok = false;
  const auto* data = reinterpret_cast<const unsigned char*>(input.data());
  try {
    ok = binary ? parser.LoadBinaryFromMemory(&g.model, &err, &warn, data, unsigned(input.size()), baseDir)
                : parser.LoadASCIIFromString(&g.model, &err, &warn, input.data(), unsigned(input.size()), baseDir);
  } catch (const std::exception& e) {
    // tinygltf mostly reports through `err`, but a few inputs (an empty data: image) make it
    // throw from the standard library.
    err = e.what();
  }
  if (!guard.refusal.empty()) {
    if (guard.refusalIsExternal) throw ExternalUriRefused(cat(path, ": ", guard.refusal));
    throw Error(cat(path, ": ", guard.refusal));
  }
  if (!ok) throw Error(cat(path, ": malformed glTF: ", err.empty() ? "unknown error" : firstLine(err)));
  if (warnings) {
    for (const std::string& line : lines(warn)) warnings->push_back(cat(path, ": ", line));
    for (const std::string& line : lines(err)) warnings->push_back(cat(path, ": ", line));
  }
  return g;
}

}  // namespace

namespace gltf {

/// Reads and parses a .gltf or .glb file (see parseGltf).
Gltf readGltf(const std::string& path, std::vector<std::string>* warnings, bool allowExternal) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(cat(path, ": no such file"));
  if (fs::is_directory(path, ec)) throw Error(cat(path, ": is a directory, expected a .gltf or .glb file"));
  if (!fs::is_regular_file(path, ec)) throw Error(cat(path, ": not a regular file"));
  uintmax_t size = fs::file_size(path, ec);
  if (ec) throw Error(cat(path, ": cannot read (", ec.message(), ")"));
  if (size > kMaxFileBytes) throw Error(cat(path, ": larger than ", kMaxFileBytes, " bytes"));
  std::string bytes(size_t(size), '\0');
  std::ifstream in(path, std::ios::binary);
  if (!in.read(bytes.data(), std::streamsize(size))) throw Error(cat(path, ": cannot read"));
  std::string dir = fs::path(path).parent_path().string();
  return parseGltf(path, bytes, dir.empty() ? "." : dir, allowExternal, warnings);
}

}  // namespace gltf

namespace {

void checkRequiredExtensions(const Gltf& g) {
  for (const std::string& ext : g.model.extensionsRequired) {
    if (ext == kUnlit || ext == kLights || ext == kTextureTransform || ext == kSpecularGlossiness ||
        ext == kMeshQuantization || ext == kTextureWebp || ext == kTransmission || ext == kIor || ext == kSpecular ||
        ext == kEmissiveStrength)
      continue;
    fail(g, cat("required extension ", ext, " is not supported"));
  }
}

// ---------------------------------------------------------------------------------------------
// Assembling the scene

void addNodeContents(const Gltf& g, const NodeVisit& v, const std::vector<BaseColorSource>& materials, Scene& scene,
                     std::map<std::pair<int, int>, PrimitiveData>& cache) {
  const tinygltf::Node& n = g.model.nodes[size_t(v.node)];
  if (n.camera >= 0) scene.cameras.push_back(readCamera(g, v));
  if (auto light = readLight(g, v, scene.warnings)) scene.lights.push_back(*light);
  if (n.mesh < 0) return;
  if (size_t(n.mesh) >= g.model.meshes.size()) fail(g, cat("node ", v.node, ": mesh ", n.mesh, " does not exist"));
  if (n.skin >= 0)
    scene.warnings.push_back(cat(g.path, ": node ", v.node, ": skin ignored (the mesh is baked in its bind pose)"));
  const tinygltf::Mesh& mesh = g.model.meshes[size_t(n.mesh)];
  for (size_t p = 0; p < mesh.primitives.size(); ++p) {
    auto key = std::make_pair(n.mesh, int(p));
    auto it = cache.find(key);
    if (it == cache.end()) it = cache.emplace(key, readPrimitive(g, materials, n.mesh, int(p), scene.warnings)).first;
    if (it->second.skipped) continue;
    scene.meshes.push_back(makeInstance(g, v, n.mesh, int(p), it->second, scene.warnings));
  }
}

/// One band count for the whole file: every primitive with transfer has the same, and the
/// bake record, if any, says that count too.
void checkTransferBands(const Gltf& g, const std::map<std::pair<int, int>, PrimitiveData>& primitives, Scene& scene) {
  for (const MeshInstance& inst : scene.meshes) {
    const int bands = primitives.at({inst.mesh, inst.primitive}).transferBands;
    if (bands == 0) continue;
    if (scene.transferBands == 0) scene.transferBands = bands;
    if (bands != scene.transferBands)
      fail(g, cat(primitiveWhere(inst.mesh, inst.primitive), ": transfer has ", bands, " bands, other primitives have ",
                  scene.transferBands));
  }
  if (scene.bakeRecord && scene.transferBands != 0 && scene.bakeRecord->bands != scene.transferBands)
    fail(g, cat("asset.extras.prt.bands: ", scene.bakeRecord->bands, ", but the transfer attributes hold ",
                scene.transferBands, " bands"));
}

/// asset.extras.prt, validated, if the file has one.
void readBakeRecord(const Gltf& g, Scene& scene) {
  const tinygltf::Value& extras = g.model.asset.extras;
  if (extras.IsObject() && extras.Has("prt"))
    scene.bakeRecord = bakeRecordFromJson(toJson(extras.Get("prt")), cat(g.path, ": asset.extras.prt"));
}

/// A bake in which every instance is a receiver (all of them animated, say) writes no transfer
/// attribute; its band count is the record's, so the receivers can still be lit from probes
/// baked with it. Called once the receivers are known.
void takeBandsFromRecord(Scene& scene) {
  if (scene.transferBands != 0 || !scene.bakeRecord || scene.meshes.empty()) return;
  for (const MeshInstance& m : scene.meshes)
    if (!m.receiverOnly) return;
  scene.transferBands = scene.bakeRecord->bands;
}

void computeBounds(const Gltf& g, Scene& scene) {
  size_t triangles = 0;
  glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
  for (const MeshInstance& inst : scene.meshes) {
    triangles += inst.triangleCount();
    for (const glm::vec3& p : inst.positions) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
  }
  if (triangles == 0) fail(g, "no triangle geometry in the default scene");
  scene.boundsMin = lo;
  scene.boundsMax = hi;
}

/// loadScene and loadSceneFromMemory: `memory` holds the document, or null to read `path`.
Scene loadSceneFrom(const std::string& path, const std::string* memory, const LoadOptions& options) {
  Scene scene;
  scene.path = path;
  Gltf g = memory ? parseGltf(path, *memory, "", false, &scene.warnings)
                  : readGltf(path, &scene.warnings, options.allowExternalUris);
  scene.allowExternalUris = options.allowExternalUris;
  checkRequiredExtensions(g);
  const std::vector<BaseColorSource> materials = readMaterials(g, scene);
  const NodeMarks marks = nodeMarks(g, options);
  const std::vector<NodeVisit> visits = visitDefaultScene(g, marks);
  std::map<std::pair<int, int>, PrimitiveData> cache;
  std::vector<char> keepStatic(g.model.nodes.size(), 0);  // inherited, per node of the default scene
  for (const NodeVisit& v : visits) {
    addNodeContents(g, v, materials, scene, cache);
    keepStatic[size_t(v.node)] = v.keepStatic;
  }
  decodeUsedTextures(g, materials, options.shadingTextures, scene);
  readBakeRecord(g, scene);
  checkTransferBands(g, cache, scene);
  computeBounds(g, scene);
  readNodes(g, scene);
  readAnimations(g, scene);
  makeAnimatedInstancesReceivers(g, scene, keepStatic);
  takeBandsFromRecord(scene);
  scene.bounceOperator = readOperator(g, scene);
  return scene;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Public: loading

Scene loadScene(const std::string& path, const LoadOptions& options) { return loadSceneFrom(path, nullptr, options); }

Scene loadSceneFromMemory(const std::string& name, const std::string& bytes, const LoadOptions& options) {
  return loadSceneFrom(name, &bytes, options);
}

}  // namespace prt
