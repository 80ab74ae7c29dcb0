// glTF 2.0 reading (loadScene, loadSceneFromMemory). The writers are in gltf_write.cpp, the URI
// sandbox in uri_guard.cpp, animation sampling in animation.cpp.
//
// One of the two files that see tinygltf (through gltf_model.h). Reading goes through
// tinygltf's parser but never trusts it with bounds: every accessor is checked against its
// buffer view and buffer before a byte is read. Images are kept encoded at load time
// (keepEncodedImage) and only the base-colour textures of materials the default scene uses are
// decoded, with stb, so a scene full of normal maps costs nothing and the writers can embed the
// original PNG/JPEG bytes instead of re-encoding them.
#include "prt/scene.h"

#include <stb_image.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>

#include "animation_labels.h"
#include "bake_record_json.h"
#include "gltf_decode.h"
#include "gltf_model.h"
#include "image_webp.h"
#include "prt/error.h"
#include "uri_guard.h"

namespace prt {

using namespace gltf;
using detail::nodeLabel;
using detail::pathName;

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr int kMaxNodeDepth = 1000;
// Limits on hostile input, checked before anything that scales with them is allocated
// (docs/robustness.md; the file size and JSON nesting limits are in uri_guard.h and uri_guard.cpp).
// Base colour textures are decoded to float RGBA (16 bytes a texel): at most 1 GiB, and no
// side beyond what GPUs load (16384).
constexpr int64_t kMaxTextureSide = 16384;
constexpr int64_t kMaxTexels = int64_t(1) << 26;
// An accessor without a buffer view reads as zeros: its count is not backed by bytes of the
// file, so it is bounded here instead of by the buffer.
constexpr size_t kMaxBufferlessCount = size_t(1) << 24;

// ---------------------------------------------------------------------------------------------
// Small helpers

std::string firstLine(const std::string& text) {
  std::string line = text.substr(0, text.find('\n'));
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
  return line;
}

bool allDigits(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); });
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) out.push_back(line);
  return out;
}

/// The sRGB decoding curve (IEC 61966-2-1), exact. Kept local: the copy in image.h belongs to
/// another part of the library.
double srgbDecode(double c) {
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
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
  parser.SetFsCallbacks(tinygltf::FsCallbacks{&guardedFileExists, &guardedExpandFilePath, &guardedReadWholeFile,
                                              &refuseWrite, &guard});
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
        ext == kMeshQuantization || ext == kTextureWebp || ext == kTransmission)
      continue;
    fail(g, cat("required extension ", ext, " is not supported"));
  }
}

// ---------------------------------------------------------------------------------------------
// Accessors (componentSize and AccessorData are in gltf_model.h)

int componentCount(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return 1;
    case TINYGLTF_TYPE_VEC2: return 2;
    case TINYGLTF_TYPE_VEC3: return 3;
    case TINYGLTF_TYPE_VEC4: return 4;
    default: return 0;  // matrices are never vertex data we read
  }
}

const char* typeName(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    default: return "a matrix type";
  }
}

}  // namespace

namespace gltf {

/// Checks accessor `index` (range, types, byte ranges of accessor, buffer view and buffer) and
/// returns a view on it. `where` names the user of the accessor, e.g. "mesh 0 / primitive 1 /
/// NORMAL".
AccessorData openAccessor(const Gltf& g, int index, const std::string& where) {
  const tinygltf::Model& m = g.model;
  if (index < 0 || size_t(index) >= m.accessors.size())
    fail(g, cat(where, ": accessor ", index, " does not exist (the file has ", m.accessors.size(), ")"));
  const tinygltf::Accessor& a = m.accessors[size_t(index)];
  if (a.sparse.isSparse) fail(g, cat(where, ": accessor ", index, " is sparse, which prt does not support"));
  AccessorData d;
  d.count = a.count;
  d.componentType = a.componentType;
  d.components = componentCount(a.type);
  d.normalized = a.normalized;
  int size = componentSize(a.componentType);
  if (size == 0) fail(g, cat(where, ": accessor ", index, " has invalid component type ", a.componentType));
  if (d.components == 0) fail(g, cat(where, ": accessor ", index, " has type ", typeName(a.type), ", expected a scalar or vector"));
  size_t elementSize = size_t(size) * size_t(d.components);
  if (a.bufferView < 0) {  // glTF: an accessor without a buffer view reads as zeros
    if (d.count > kMaxBufferlessCount)
      fail(g, cat(where, ": accessor ", index, " has ", d.count, " elements but no buffer view (at most ",
                  kMaxBufferlessCount, ")"));
    return d;
  }
  if (size_t(a.bufferView) >= m.bufferViews.size())
    fail(g, cat(where, ": accessor ", index, " uses buffer view ", a.bufferView, ", which does not exist"));
  const tinygltf::BufferView& view = m.bufferViews[size_t(a.bufferView)];
  if (view.buffer < 0 || size_t(view.buffer) >= m.buffers.size())
    fail(g, cat(where, ": buffer view ", a.bufferView, " uses buffer ", view.buffer, ", which does not exist"));
  const tinygltf::Buffer& buffer = m.buffers[size_t(view.buffer)];
  if (view.byteOffset > buffer.data.size() || view.byteLength > buffer.data.size() - view.byteOffset)
    fail(g, cat(where, ": buffer view ", a.bufferView, " (bytes ", view.byteOffset, "..",
                view.byteOffset + view.byteLength, ") runs past the end of buffer ", view.buffer,
                " (", buffer.data.size(), " bytes)"));
  d.stride = view.byteStride ? view.byteStride : elementSize;
  if (d.stride < elementSize)
    fail(g, cat(where, ": buffer view ", a.bufferView, " has byteStride ", view.byteStride,
                ", smaller than one element (", elementSize, " bytes)"));
  if (d.count > 0) {
    // The last element ends at byteOffset + (count-1)·stride + elementSize; written so that
    // nothing overflows whatever count the file claims.
    bool fits = a.byteOffset <= view.byteLength && elementSize <= view.byteLength - a.byteOffset &&
                (d.count - 1) <= (view.byteLength - a.byteOffset - elementSize) / d.stride;
    if (!fits)
      fail(g, cat(where, ": accessor ", index, " (", d.count, " elements, stride ", d.stride,
                  ", offset ", a.byteOffset, ") runs past the end of buffer view ", a.bufferView,
                  " (", view.byteLength, " bytes)"));
  }
  d.bytes = buffer.data.data() + view.byteOffset + a.byteOffset;
  return d;
}

}  // namespace gltf

namespace {

void requireType(const Gltf& g, const AccessorData& d, const std::string& where,
                 std::initializer_list<int> componentCounts) {
  if (std::find(componentCounts.begin(), componentCounts.end(), d.components) == componentCounts.end()) {
    std::string expected;
    for (int c : componentCounts)
      expected += cat(expected.empty() ? "" : " or ", typeName(c == 1 ? TINYGLTF_TYPE_SCALAR : c));
    fail(g, cat(where, ": accessor has ", d.components, " components, expected ", expected));
  }
}

void requireCount(const Gltf& g, const AccessorData& d, const std::string& where, size_t expected) {
  if (d.count != expected)
    fail(g, cat(where, ": ", d.count, " values, expected ", expected, " (the POSITION count)"));
}

template <int N>
std::vector<glm::vec<N, float>> readVectors(const AccessorData& d) {
  std::vector<glm::vec<N, float>> out(d.count);
  for (size_t i = 0; i < d.count; ++i)
    for (int c = 0; c < N; ++c) out[i][c] = static_cast<float>(d.get(i, c));
  return out;
}

}  // namespace

namespace gltf {

/// Index values of a primitive (or 0..n-1 without indices), each checked against the vertex count.
std::vector<uint32_t> readIndices(const Gltf& g, const tinygltf::Primitive& prim,
                                  const std::string& where, size_t vertexCount) {
  std::vector<uint32_t> out;
  if (prim.indices < 0) {
    out.resize(vertexCount);
    for (size_t i = 0; i < vertexCount; ++i) out[i] = static_cast<uint32_t>(i);
    return out;
  }
  std::string here = cat(where, " / indices");
  AccessorData d = openAccessor(g, prim.indices, here);
  requireType(g, d, here, {1});
  if (d.normalized || (d.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
                       d.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
                       d.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT))
    fail(g, cat(here, ": component type ", d.componentType, ", expected an unsigned integer type"));
  out.resize(d.count);
  for (size_t i = 0; i < d.count; ++i) {
    double v = d.get(i, 0);
    if (v >= double(vertexCount))
      fail(g, cat(here, ": index ", i, " is ", uint64_t(v), ", out of range (the primitive has ",
                  vertexCount, " vertices)"));
    out[i] = static_cast<uint32_t>(v);
  }
  return out;
}

/// Triangle list from TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN indices, in glTF's winding
/// (strips alternate: triangle i is p_i, p_{i+1+i%2}, p_{i+2-i%2}; fans are p_{i+1}, p_{i+2}, p_0).
std::vector<uint32_t> toTriangleList(const Gltf& g, int mode, const std::vector<uint32_t>& in,
                                     const std::string& where) {
  std::vector<uint32_t> out;
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    if (in.size() % 3 != 0) fail(g, cat(where, ": ", in.size(), " indices, not a multiple of 3"));
    return in;
  }
  size_t n = in.size() < 3 ? 0 : in.size() - 2;
  out.reserve(3 * n);
  for (size_t i = 0; i < n; ++i) {
    if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      size_t odd = i % 2;
      out.insert(out.end(), {in[i], in[i + 1 + odd], in[i + 2 - odd]});
    } else {
      out.insert(out.end(), {in[i + 1], in[i + 2], in[0]});
    }
  }
  return out;
}

/// Per vertex, the area-weighted sum of the normals of the triangles that use it, normalised;
/// (0, 1, 0) for a vertex no triangle uses.
std::vector<glm::vec3> flatVertexNormals(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& indices) {
  std::vector<glm::dvec3> sum(positions.size(), glm::dvec3(0.0));
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    const glm::dvec3 p0(positions[indices[t]]);
    const glm::dvec3 n = glm::cross(glm::dvec3(positions[indices[t + 1]]) - p0, glm::dvec3(positions[indices[t + 2]]) - p0);
    for (size_t k = 0; k < 3; ++k) sum[indices[t + k]] += n;
  }
  std::vector<glm::vec3> out(positions.size(), glm::vec3(0, 1, 0));
  for (size_t v = 0; v < sum.size(); ++v) {
    const double len = glm::length(sum[v]);
    if (len > 0.0 && std::isfinite(len)) out[v] = glm::vec3(sum[v] / len);
  }
  return out;
}

}  // namespace gltf

namespace {

// ---------------------------------------------------------------------------------------------
// Primitives (read once per mesh/primitive, in the primitive's own space)

/// A triangle primitive as stored in the file, before any node transform.
struct PrimitiveData {
  bool skipped = true;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;  // empty if absent
  std::vector<glm::vec2> texcoords;
  std::vector<glm::vec4> colors;
  std::vector<uint32_t> indices;   // triangle list, glTF winding, degenerate triangles dropped
  std::vector<uint32_t> fileVertex;  // MeshInstance::fileVertex
  int material = -1;
  int transferBands = 0;
  std::vector<glm::vec3> transfer;
  std::vector<glm::vec3> transferBack;  // _PRT_SH_BACK_ (double-sided primitives of a bake)
  std::vector<float> transferDirect, transferDirectBack;  // _PRT_SH_DIRECT_, _PRT_SH_BACK_DIRECT_
};

/// Faces whose unit normals have a dot product at least this share a vertex under flat
/// normals: within 0.1°, which float positions of one plane never exceed, while real edges of
/// a mesh that needs flat shading are far sharper.
constexpr double kSameOrientation = 0.99999848;  // cos(0.1°)

/// Where a material's base colour comes from: the glTF texture (decoded later, only if an
/// instance uses the material), the TEXCOORD_n it reads and its KHR_texture_transform.
struct BaseColorSource {
  int texture = -1;
  int texCoord = 0;
  glm::dmat3 uvTransform{1.0};
  int transmissionTexture = -1;  // KHR_materials_transmission's, read at the same coordinates
};

const char* modeName(int mode) {
  static const char* names[] = {"POINTS", "LINES", "LINE_LOOP", "LINE_STRIP"};
  return mode >= 0 && mode < 4 ? names[mode] : "?";
}

/// Refuses a non-finite value among values[first], values[first + step], ... (vertex-major
/// data: step = values per vertex).
template <class Vec>
void requireFinite(const Gltf& g, const std::vector<Vec>& values, const std::string& where, size_t first = 0,
                   size_t step = 1) {
  for (size_t i = first, v = 0; i < values.size(); i += step, ++v)
    for (int c = 0; c < Vec::length(); ++c)
      if (!std::isfinite(values[i][c])) fail(g, cat(where, ": vertex ", v, " is not finite"));
}

std::vector<glm::vec3> readPositions(const Gltf& g, int accessor, const std::string& where) {
  std::string here = cat(where, " / POSITION");
  AccessorData d = openAccessor(g, accessor, here);
  requireType(g, d, here, {3});
  std::vector<glm::vec3> p = readVectors<3>(d);
  for (size_t v = 0; v < p.size(); ++v)
    if (!std::isfinite(p[v].x) || !std::isfinite(p[v].y) || !std::isfinite(p[v].z))
      fail(g, cat(here, ": vertex ", v, " is not finite"));
  return p;
}

/// Drops zero-area and repeated-index triangles, with one warning for the primitive. The test
/// is exact (area computed in double from float inputs): only truly degenerate triangles are
/// caught, the ones whose normal is undefined. Vertices stay as they are, so per-vertex
/// transfer still lines up with the file's vertices, and every command that reads the file
/// (the baked one too, which keeps the file's indices) drops the same triangles.
void removeDegenerate(const Gltf& g, PrimitiveData& p, const std::string& where, std::vector<std::string>& warnings) {
  std::vector<uint32_t> kept;
  kept.reserve(p.indices.size());
  size_t dropped = 0, first = 0;
  for (size_t t = 0; t < p.indices.size() / 3; ++t) {
    uint32_t a = p.indices[3 * t], b = p.indices[3 * t + 1], c = p.indices[3 * t + 2];
    glm::dvec3 e1 = glm::dvec3(p.positions[b]) - glm::dvec3(p.positions[a]);
    glm::dvec3 e2 = glm::dvec3(p.positions[c]) - glm::dvec3(p.positions[a]);
    bool degenerate = a == b || b == c || a == c || glm::dot(glm::cross(e1, e2), glm::cross(e1, e2)) == 0.0;
    if (!degenerate) {
      kept.insert(kept.end(), {a, b, c});
      continue;
    }
    if (dropped++ == 0) first = t;
  }
  if (dropped)
    warnings.push_back(cat(g.path, ": ", where, ": dropped ", dropped, " degenerate (zero-area) triangle",
                           dropped == 1 ? cat(" (triangle ", first, ")") : cat("s (the first is triangle ", first, ")"),
                           " of ", p.indices.size() / 3));
  p.indices = std::move(kept);
}

template <class T>
void gather(std::vector<T>& values, const std::vector<uint32_t>& from, size_t perVertex = 1) {
  if (values.empty()) return;
  std::vector<T> out;
  out.reserve(from.size() * perVertex);
  for (uint32_t v : from) out.insert(out.end(), values.begin() + std::ptrdiff_t(v * perVertex),
                                     values.begin() + std::ptrdiff_t((v + 1) * perVertex));
  values = std::move(out);
}

/// glTF: a primitive without NORMAL has flat normals. Transfer is stored per vertex, so a
/// vertex shared by faces of different orientation is split, one copy per orientation, each
/// with the vertex's UVs, colour and (in an old baked file) transfer; faces of one orientation
/// keep sharing it (a floor of many triangles is not unwelded). The first copy keeps the file's
/// index, so a primitive that needs no split keeps its vertices as they are.
void splitForFlatNormals(PrimitiveData& p) {
  const size_t n = p.positions.size(), triangles = p.indices.size() / 3;
  std::vector<glm::dvec3> face(triangles);
  for (size_t t = 0; t < triangles; ++t) {
    const uint32_t* i = &p.indices[3 * t];
    glm::dvec3 p0(p.positions[i[0]]);
    face[t] = glm::normalize(glm::cross(glm::dvec3(p.positions[i[1]]) - p0, glm::dvec3(p.positions[i[2]]) - p0));
  }
  // Per file vertex, the orientations met so far: (the first face's normal, its vertex).
  std::vector<std::vector<std::pair<glm::dvec3, uint32_t>>> copies(n);
  std::vector<uint32_t> fileVertex(n);
  for (size_t v = 0; v < n; ++v) fileVertex[v] = uint32_t(v);
  for (size_t t = 0; t < triangles; ++t) {
    for (int k = 0; k < 3; ++k) {
      uint32_t& index = p.indices[3 * t + size_t(k)];
      auto& list = copies[index];
      auto same = std::find_if(list.begin(), list.end(),
                               [&](const auto& c) { return glm::dot(c.first, face[t]) >= kSameOrientation; });
      if (same != list.end()) {
        index = same->second;
        continue;
      }
      const uint32_t copy = list.empty() ? index : uint32_t(fileVertex.size());
      if (!list.empty()) fileVertex.push_back(index);
      list.emplace_back(face[t], copy);
      index = copy;
    }
  }
  if (fileVertex.size() > n) {
    gather(p.positions, fileVertex);
    gather(p.texcoords, fileVertex);
    gather(p.colors, fileVertex);
    gather(p.transfer, fileVertex, size_t(p.transferBands) * size_t(p.transferBands));
    gather(p.transferBack, fileVertex, size_t(p.transferBands) * size_t(p.transferBands));
    gather(p.transferDirect, fileVertex, size_t(p.transferBands) * size_t(p.transferBands));
    gather(p.transferDirectBack, fileVertex, size_t(p.transferBands) * size_t(p.transferBands));
    p.fileVertex = std::move(fileVertex);
  }
  p.normals = flatVertexNormals(p.positions, p.indices);
}

/// Reads the transfer sets a primitive has (docs/formats.md): _PRT_SH_00 .. _PRT_SH_{n²-1} (RGB),
/// _PRT_SH_BACK_NN (RGB, the back side), _PRT_SH_DIRECT_NN and _PRT_SH_BACK_DIRECT_NN (SCALAR,
/// the colourless direct parts), into vertex-major arrays. Each set other than the front needs
/// the front set's band count, and the back's direct part needs the back set.
void readTransferSets(const Gltf& g, const tinygltf::Primitive& prim, PrimitiveData& p, const std::string& where) {
  std::map<int, int> coefficients[4];  // per set (bit 0: back, bit 1: direct): index -> accessor
  for (const auto& [name, accessor] : prim.attributes) {
    if (name.rfind(kTransferPrefix, 0) != 0) continue;
    int set = 0;  // the longest prefix that matches: BACK_DIRECT_ before DIRECT_ and BACK_
    for (int s = 3; s > 0 && set == 0; --s)
      if (name.rfind(transferPrefix(s & 1, s & 2), 0) == 0) set = s;
    const char* prefixName = transferPrefix(set & 1, set & 2);
    std::string digits = name.substr(std::strlen(prefixName));
    if (!allDigits(digits) || digits.size() > 4)
      fail(g, cat(where, ": attribute ", name, " is not a transfer coefficient (expected ", prefixName, "NN)"));
    coefficients[set][std::stoi(digits)] = accessor;
  }
  for (int set = 0; set < 4; ++set) {
    if (coefficients[set].empty()) continue;
    const bool back = set & 1, direct = set & 2;
    const char* prefixName = transferPrefix(back, direct);
    int count = static_cast<int>(coefficients[set].size());
    int bands = static_cast<int>(std::lround(std::sqrt(double(count))));
    const char* what = direct ? (back ? " back-side direct" : " direct") : (back ? " back-side" : "");
    if (bands * bands != count || bands > sh::kMaxBands)
      fail(g, cat(where, ": ", count, what, " transfer attributes, expected a square number (bands²) of at most ",
                  sh::kMaxBands * sh::kMaxBands));
    for (int i = 0; i < count; ++i)
      if (!coefficients[set].count(i))
        fail(g, cat(where, ": transfer attribute ", coefficientName(i, back, direct), " is missing (", count, " found)"));
    if (set != 0 && bands != p.transferBands)
      fail(g, cat(where, ": ", count, what, " transfer attributes (", prefixName, "NN), but ",
                  p.transferBands * p.transferBands, " front ones (", kTransferPrefix, "NN)"));
    if (set == 3 && p.transferBack.empty())
      fail(g, cat(where, ": back-side direct transfer attributes (", prefixName, "NN) without back-side ones (",
                  kBackTransferPrefix, "NN)"));
    size_t n = p.positions.size(), k = size_t(count);
    p.transferBands = bands;
    std::vector<glm::vec3>* rgb = direct ? nullptr : (back ? &p.transferBack : &p.transfer);
    std::vector<float>* grey = direct ? (back ? &p.transferDirectBack : &p.transferDirect) : nullptr;
    if (rgb) rgb->assign(n * k, glm::vec3(0.0f));
    if (grey) grey->assign(n * k, 0.0f);
    for (const auto& [i, accessor] : coefficients[set]) {
      std::string here = cat(where, " / ", coefficientName(i, back, direct));
      AccessorData d = openAccessor(g, accessor, here);
      requireType(g, d, here, {direct ? 1 : 3});
      requireCount(g, d, here, n);
      for (size_t v = 0; v < n; ++v) {
        if (grey) {
          float x = static_cast<float>(d.get(v, 0));
          if (!std::isfinite(x)) fail(g, cat(here, ": vertex ", v, " is not finite"));
          (*grey)[v * k + size_t(i)] = x;
        } else {
          for (int c = 0; c < 3; ++c) (*rgb)[v * k + size_t(i)][c] = static_cast<float>(d.get(v, c));
        }
      }
      if (rgb) requireFinite(g, *rgb, here, i, k);
    }
  }
}

PrimitiveData readPrimitive(const Gltf& g, const std::vector<BaseColorSource>& materials, int meshIndex,
                            int primIndex, std::vector<std::string>& warnings) {
  const tinygltf::Primitive& prim = g.model.meshes[size_t(meshIndex)].primitives[size_t(primIndex)];
  std::string where = primitiveWhere(meshIndex, primIndex);
  PrimitiveData p;
  if (prim.mode >= TINYGLTF_MODE_POINTS && prim.mode <= TINYGLTF_MODE_LINE_STRIP) {
    warnings.push_back(cat(g.path, ": ", where, ": skipping mode ", modeName(prim.mode),
                           " (only triangles are baked)"));
    return p;
  }
  if (prim.mode < TINYGLTF_MODE_TRIANGLES || prim.mode > TINYGLTF_MODE_TRIANGLE_FAN)
    fail(g, cat(where, ": unknown mode ", prim.mode));
  auto position = prim.attributes.find("POSITION");
  if (position == prim.attributes.end()) {
    warnings.push_back(cat(g.path, ": ", where, ": skipping a primitive without POSITION"));
    return p;
  }
  if (prim.material >= 0 && size_t(prim.material) >= g.model.materials.size())
    fail(g, cat(where, ": material ", prim.material, " does not exist"));
  p.skipped = false;
  p.material = prim.material;
  p.positions = readPositions(g, position->second, where);
  size_t n = p.positions.size();

  if (auto it = prim.attributes.find("NORMAL"); it != prim.attributes.end()) {
    std::string here = cat(where, " / NORMAL");
    AccessorData d = openAccessor(g, it->second, here);
    requireType(g, d, here, {3});
    requireCount(g, d, here, n);
    p.normals = readVectors<3>(d);
  }
  const BaseColorSource* source = p.material >= 0 ? &materials[size_t(p.material)] : nullptr;
  std::string uvName = cat("TEXCOORD_", source ? source->texCoord : 0);
  if (auto it = prim.attributes.find(uvName); it != prim.attributes.end()) {
    std::string here = cat(where, " / ", uvName);
    AccessorData d = openAccessor(g, it->second, here);
    requireType(g, d, here, {2});
    requireCount(g, d, here, n);
    p.texcoords = readVectors<2>(d);
    if (source && source->uvTransform != glm::dmat3(1.0))
      for (glm::vec2& uv : p.texcoords) uv = glm::vec2(source->uvTransform * glm::dvec3(uv, 1.0));
  } else if (source && source->texture >= 0) {
    warnings.push_back(cat(g.path, ": ", where, ": no ", uvName, " for the base colour texture; texture ignored"));
  }
  if (auto it = prim.attributes.find("COLOR_0"); it != prim.attributes.end()) {
    std::string here = cat(where, " / COLOR_0");
    AccessorData d = openAccessor(g, it->second, here);
    requireType(g, d, here, {3, 4});
    requireCount(g, d, here, n);
    p.colors.assign(n, glm::vec4(1.0f));
    for (size_t v = 0; v < n; ++v)
      for (int c = 0; c < d.components; ++c) p.colors[v][c] = static_cast<float>(d.get(v, c));
    requireFinite(g, p.colors, here);
  }
  p.indices = toTriangleList(g, prim.mode, readIndices(g, prim, where, n), cat(where, " / indices"));
  removeDegenerate(g, p, where, warnings);
  readTransferSets(g, prim, p, where);
  if (p.normals.empty()) splitForFlatNormals(p);
  return p;
}

// ---------------------------------------------------------------------------------------------
// Node hierarchy

glm::dmat4 localTransform(const Gltf& g, int index) {
  const tinygltf::Node& n = g.model.nodes[size_t(index)];
  auto checkSize = [&](const std::vector<double>& v, size_t expected, const char* what) {
    if (!v.empty() && v.size() != expected)
      fail(g, cat("node ", index, ": ", what, " has ", v.size(), " values, expected ", expected));
    for (double x : v)
      if (!std::isfinite(x)) fail(g, cat("node ", index, ": ", what, " is not finite"));
  };
  checkSize(n.matrix, 16, "matrix");
  checkSize(n.translation, 3, "translation");
  checkSize(n.rotation, 4, "rotation");
  checkSize(n.scale, 3, "scale");
  if (!n.matrix.empty()) return glm::make_mat4(n.matrix.data());  // both column-major
  glm::dmat4 t(1.0), r(1.0), s(1.0);
  if (!n.translation.empty()) t = glm::translate(glm::dmat4(1.0), glm::make_vec3(n.translation.data()));
  if (!n.rotation.empty()) {
    glm::dquat q(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);  // glTF is x,y,z,w
    double len = glm::length(q);
    if (len == 0.0) fail(g, cat("node ", index, ": rotation is a zero quaternion"));
    r = glm::mat4_cast(q / len);
  }
  if (!n.scale.empty()) s = glm::scale(glm::dmat4(1.0), glm::make_vec3(n.scale.data()));
  return t * r * s;
}

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

struct Traversal {
  const Gltf& g;
  const NodeMarks& marks;
  std::vector<char> visited, onPath;
  std::vector<NodeVisit> out;

  void visit(int node, const NodeVisit& parent, int depth) {
    if (node < 0 || size_t(node) >= g.model.nodes.size()) fail(g, cat("node ", node, " does not exist"));
    if (onPath[size_t(node)]) fail(g, cat("node ", node, ": the node hierarchy has a cycle"));
    if (visited[size_t(node)]) fail(g, cat("node ", node, " is reached twice (glTF nodes form a tree)"));
    if (depth > kMaxNodeDepth) fail(g, cat("node ", node, ": node hierarchy deeper than ", kMaxNodeDepth, " levels"));
    visited[size_t(node)] = onPath[size_t(node)] = 1;
    const tinygltf::Node& n = g.model.nodes[size_t(node)];
    NodeVisit v{node, parent.world * localTransform(g, node),
                parent.receiver != ReceiverReason::None ? parent.receiver : marks.receiver[size_t(node)],
                parent.keepStatic || marks.keepStatic[size_t(node)] != 0};
    out.push_back(v);
    for (int child : n.children) visit(child, v, depth + 1);
    onPath[size_t(node)] = 0;
  }
};

std::vector<int> rootNodes(const Gltf& g) {
  const tinygltf::Model& m = g.model;
  if (!m.scenes.empty()) {
    int s = m.defaultScene >= 0 ? m.defaultScene : 0;
    if (size_t(s) >= m.scenes.size()) fail(g, cat("default scene ", s, " does not exist"));
    return m.scenes[size_t(s)].nodes;
  }
  std::vector<char> isChild(m.nodes.size(), 0);
  for (const tinygltf::Node& n : m.nodes)
    for (int c : n.children)
      if (c >= 0 && size_t(c) < m.nodes.size()) isChild[size_t(c)] = 1;
  std::vector<int> roots;
  for (size_t i = 0; i < m.nodes.size(); ++i)
    if (!isChild[i]) roots.push_back(int(i));
  return roots;
}

/// extras {"prt": {"receiver": true | false}}: true or false when given, empty otherwise.
std::optional<bool> extrasReceiver(const tinygltf::Node& n) {
  if (!n.extras.IsObject() || !n.extras.Has("prt")) return std::nullopt;
  const tinygltf::Value& prt = n.extras.Get("prt");
  if (!prt.IsObject() || !prt.Has("receiver")) return std::nullopt;
  const tinygltf::Value& r = prt.Get("receiver");
  if (!r.IsBool()) return std::nullopt;
  return r.Get<bool>();
}

NodeMarks nodeMarks(const Gltf& g, const LoadOptions& options) {
  const auto& nodes = g.model.nodes;
  NodeMarks marks{std::vector<ReceiverReason>(nodes.size(), ReceiverReason::None), std::vector<char>(nodes.size(), 0)};
  for (size_t i = 0; i < nodes.size(); ++i) {
    const std::optional<bool> r = extrasReceiver(nodes[i]);
    if (r && *r) marks.receiver[i] = ReceiverReason::Extras;
    marks.keepStatic[i] = r && !*r;
  }
  for (const std::string& entry : options.receiverNodes) {
    bool found = false;
    for (size_t i = 0; i < nodes.size(); ++i)
      if (nodes[i].name == entry) {
        marks.receiver[i] = ReceiverReason::Option;
        found = true;
      }
    bool numeric = allDigits(entry) && entry.size() < 10;
    if (numeric && size_t(std::stoul(entry)) < nodes.size()) {
      marks.receiver[std::stoul(entry)] = ReceiverReason::Option;
      found = true;
    }
    if (!found) fail(g, cat("no node named '", entry, "'"));
  }
  return marks;
}

// ---------------------------------------------------------------------------------------------
// Instances: a primitive placed in the world by one node

/// Area-weighted vertex normals: each triangle adds its cross product, whose length is twice
/// its area, to its three vertices.
std::vector<glm::dvec3> areaWeightedNormals(const MeshInstance& inst) {
  std::vector<glm::dvec3> sum(inst.positions.size(), glm::dvec3(0.0));
  for (size_t t = 0; t < inst.triangleCount(); ++t) {
    const uint32_t* i = &inst.indices[3 * t];
    glm::dvec3 p0(inst.positions[i[0]]), p1(inst.positions[i[1]]), p2(inst.positions[i[2]]);
    glm::dvec3 n = glm::cross(p1 - p0, p2 - p0);
    for (int k = 0; k < 3; ++k) sum[i[k]] += n;
  }
  return sum;
}

glm::vec3 unitOr(const glm::dvec3& v, const glm::vec3& fallback) {
  double len = glm::length(v);
  return len > 0.0 && std::isfinite(len) ? glm::vec3(v / len) : fallback;
}

/// World normals: given ones through the inverse transpose, computed ones where the file has
/// none or a zero (or non-finite) normal. Returns how many given normals were replaced.
size_t setNormals(MeshInstance& inst, const PrimitiveData& p, const glm::dmat3& linear) {
  // cofactor(M) = det(M)·M^-T; scaled by sign(det) it is a positive multiple of M^-T and
  // stays defined for singular M.
  glm::dmat3 cof(glm::cross(linear[1], linear[2]), glm::cross(linear[2], linear[0]),
                 glm::cross(linear[0], linear[1]));
  if (glm::determinant(linear) < 0.0) cof = -cof;
  size_t n = inst.positions.size();
  inst.normals.assign(n, glm::vec3(0.0f));
  std::vector<glm::dvec3> computed;
  size_t repaired = 0;
  for (size_t v = 0; v < n; ++v) {
    glm::dvec3 world = p.normals.empty() ? glm::dvec3(0.0) : cof * glm::dvec3(p.normals[v]);
    double len = glm::length(world);
    if (len > 0.0 && std::isfinite(len)) {
      inst.normals[v] = glm::vec3(world / len);
      continue;
    }
    if (computed.empty()) computed = areaWeightedNormals(inst);
    inst.normals[v] = unitOr(computed[v], glm::vec3(0, 1, 0));
    ++repaired;
  }
  return p.normals.empty() ? 0 : repaired;
}

MeshInstance makeInstance(const Gltf& g, const NodeVisit& visit, int meshIndex, int primIndex,
                          const PrimitiveData& p, std::vector<std::string>& warnings) {
  const tinygltf::Node& node = g.model.nodes[size_t(visit.node)];
  const tinygltf::Mesh& mesh = g.model.meshes[size_t(meshIndex)];
  MeshInstance inst;
  inst.name = cat(node.name.empty() ? cat("node ", visit.node) : node.name, "/",
                  mesh.name.empty() ? cat("mesh ", meshIndex) : mesh.name, "/primitive ", primIndex);
  inst.node = visit.node;
  inst.mesh = meshIndex;
  inst.primitive = primIndex;
  inst.world = visit.world;
  inst.material = p.material;
  inst.receiverOnly = visit.receiver != ReceiverReason::None;
  inst.receiverReason = visit.receiver;
  inst.positions.resize(p.positions.size());
  for (size_t v = 0; v < p.positions.size(); ++v) {
    glm::dvec4 w = visit.world * glm::dvec4(glm::dvec3(p.positions[v]), 1.0);
    inst.positions[v] = glm::vec3(w);
    if (!std::isfinite(inst.positions[v].x) || !std::isfinite(inst.positions[v].y) ||
        !std::isfinite(inst.positions[v].z))
      fail(g, cat("node ", visit.node, " / ", primitiveWhere(meshIndex, primIndex), " / POSITION: vertex ", v,
                  " is not finite after the node transform"));
  }
  inst.indices = p.indices;
  glm::dmat3 linear(visit.world);
  // A mirroring transform turns counter-clockwise triangles clockwise; swapping two corners
  // keeps them front-facing (the glTF spec asks renderers to do the same).
  if (glm::determinant(linear) < 0.0)
    for (size_t t = 0; t < inst.triangleCount(); ++t) std::swap(inst.indices[3 * t + 1], inst.indices[3 * t + 2]);
  if (size_t repaired = setNormals(inst, p, linear))
    warnings.push_back(cat(g.path, ": node ", visit.node, " / ", primitiveWhere(meshIndex, primIndex), ": ",
                           repaired, " zero or non-finite normals replaced by face normals"));
  inst.texcoords = p.texcoords;
  inst.colors = p.colors;
  inst.fileVertex = p.fileVertex;
  inst.transfer = p.transfer;
  inst.transferBack = p.transferBack;
  inst.transferDirect = p.transferDirect;
  inst.transferDirectBack = p.transferDirectBack;
  return inst;
}

// ---------------------------------------------------------------------------------------------
// Materials and textures

static_assert(Texture::kRepeat == TINYGLTF_TEXTURE_WRAP_REPEAT && Texture::kClampToEdge == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE &&
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
    fail(g, cat(where, ": image ", w, "x", h, " is too large (at most ", kMaxTextureSide, " a side, ",
                kMaxTexels, " texels)"));
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
  if (source < 0 || size_t(source) >= m.images.size())
    fail(g, cat(where, ": image ", source, " does not exist"));
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

/// A number array of `size` values (glTF JSON held by tinygltf), checked as it is read.
std::vector<double> numbers(const Gltf& g, const tinygltf::Value& v, size_t size, const std::string& where) {
  if (!v.IsArray() || v.ArrayLen() != size) fail(g, cat(where, ": expected an array of ", size, " numbers"));
  std::vector<double> out;
  for (size_t i = 0; i < size; ++i) {
    const tinygltf::Value& x = v.Get(int(i));
    if (!x.IsNumber() || !std::isfinite(x.GetNumberAsDouble())) fail(g, cat(where, ": value ", i, " is not a finite number"));
    out.push_back(x.GetNumberAsDouble());
  }
  return out;
}

/// KHR_texture_transform as the affine map uv -> T·R·S·uv of its specification (rotation
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

/// alphaMode, alphaCutoff and KHR_materials_transmission. The transmission texture is read at
/// the base colour's texture coordinates (MeshInstance holds one set): one that names another
/// TEXCOORD_n or another KHR_texture_transform is ignored with a warning (the factor stays),
/// unless the material has no base colour texture, whose coordinates it then decides.
void readAlphaAndTransmission(const Gltf& g, const tinygltf::Material& src, const std::string& where, Material& mat,
                              BaseColorSource& source, std::vector<std::string>& warnings) {
  if (src.alphaMode == "MASK") mat.alphaMode = Material::AlphaMode::Mask;
  else if (src.alphaMode == "BLEND") mat.alphaMode = Material::AlphaMode::Blend;
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
    warnings.push_back(cat(g.path, ": ", here, ": transmissionTexture uses other texture coordinates than the base "
                                              "colour texture; ignored (transmissionFactor only)"));
    return;
  }
  source.transmissionTexture = index.Get<int>();
}

/// Reads the materials; their base colour textures are decoded later (decodeUsedTextures),
/// once the instances show which materials the default scene uses.
std::vector<BaseColorSource> readMaterials(const Gltf& g, Scene& scene) {
  const tinygltf::Model& m = g.model;
  std::vector<BaseColorSource> sources;
  for (size_t i = 0; i < m.materials.size(); ++i) {
    const tinygltf::Material& src = m.materials[i];
    const std::string where = cat("material ", i);
    Material mat;
    mat.name = src.name;
    BaseColorSource source;
    int texture = -1;
    auto specGloss = src.extensions.find(kSpecularGlossiness);
    if (specGloss != src.extensions.end() && specGloss->second.IsObject()) {
      // The extension replaces the metallic-roughness model: its diffuse colour is the albedo.
      const tinygltf::Value& sg = specGloss->second;
      const std::string here = cat(where, " / ", kSpecularGlossiness);
      if (sg.Has("diffuseFactor"))
        mat.baseColorFactor = glm::vec4(glm::make_vec4(numbers(g, sg.Get("diffuseFactor"), 4, cat(here, " / diffuseFactor")).data()));
      if (sg.Has("diffuseTexture")) {
        const tinygltf::Value& info = sg.Get("diffuseTexture");
        const tinygltf::Value& index = info.Get("index");
        if (!info.IsObject() || !index.IsInt())
          fail(g, cat(here, " / diffuseTexture: expected an object with an integer index"));
        texture = index.Get<int>();
        const tinygltf::Value& texCoord = info.Get("texCoord");
        if (texCoord.IsInt()) source.texCoord = texCoord.Get<int>();
        const tinygltf::Value& ext = info.Get("extensions");
        if (ext.IsObject()) readTextureTransform(g, ext.Get<tinygltf::Value::Object>(), cat(here, " / diffuseTexture"), source);
      }
    } else {
      const std::vector<double>& f = src.pbrMetallicRoughness.baseColorFactor;
      if (f.size() == 4) mat.baseColorFactor = glm::vec4(f[0], f[1], f[2], f[3]);
      else if (!f.empty()) fail(g, cat(where, ": baseColorFactor has ", f.size(), " values, expected 4"));
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
    scene.materials.push_back(mat);
    sources.push_back(source);
  }
  return sources;
}

/// Decodes the base colour textures of the materials the instances use, each glTF texture
/// once, in the order of the materials: a texture only unused meshes need is never read.
void decodeUsedTextures(const Gltf& g, const std::vector<BaseColorSource>& sources, Scene& scene) {
  std::vector<char> used(scene.materials.size(), 0);
  for (const MeshInstance& inst : scene.meshes)
    if (inst.material >= 0) used[size_t(inst.material)] = 1;
  std::map<std::pair<int, bool>, int> slot;  // (glTF texture, sRGB) -> Scene::textures
  auto decode = [&](int texture, bool srgb) {
    auto [it, fresh] = slot.emplace(std::make_pair(texture, srgb), int(scene.textures.size()));
    if (fresh) scene.textures.push_back(decodeBaseColorTexture(g, texture, srgb));
    return it->second;
  };
  for (size_t i = 0; i < sources.size(); ++i) {
    if (!used[i]) continue;
    if (sources[i].texture >= 0) scene.materials[i].baseColorTexture = decode(sources[i].texture, true);
    if (sources[i].transmissionTexture >= 0)
      scene.materials[i].transmissionTexture = decode(sources[i].transmissionTexture, false);
  }
}

// ---------------------------------------------------------------------------------------------
// Cameras and lights

Camera readCamera(const Gltf& g, const NodeVisit& v) {
  const tinygltf::Node& n = g.model.nodes[size_t(v.node)];
  if (size_t(n.camera) >= g.model.cameras.size()) fail(g, cat("node ", v.node, ": camera ", n.camera, " does not exist"));
  const tinygltf::Camera& src = g.model.cameras[size_t(n.camera)];
  Camera c;
  c.name = !src.name.empty() ? src.name : n.name;
  c.node = v.node;
  c.world = v.world;
  c.perspective = src.type != "orthographic";
  if (c.perspective) {
    c.yfov = src.perspective.yfov;
    c.aspectRatio = src.perspective.aspectRatio;
    c.znear = src.perspective.znear;
    c.zfar = src.perspective.zfar;
  } else {
    c.xmag = src.orthographic.xmag;
    c.ymag = src.orthographic.ymag;
    c.znear = src.orthographic.znear;
    c.zfar = src.orthographic.zfar;
  }
  for (double x : {c.yfov, c.aspectRatio, c.znear, c.zfar, c.xmag, c.ymag})
    if (!std::isfinite(x)) fail(g, cat("camera ", n.camera, ": a parameter is not finite"));
  return c;
}

/// The KHR_lights_punctual light a node carries, if any.
std::optional<PunctualLight> readLight(const Gltf& g, const NodeVisit& v, std::vector<std::string>& warnings) {
  const tinygltf::Node& n = g.model.nodes[size_t(v.node)];
  auto ext = n.extensions.find(kLights);
  if (ext == n.extensions.end() || !ext->second.IsObject() || !ext->second.Has("light")) return std::nullopt;
  const tinygltf::Value& index = ext->second.Get("light");
  if (!index.IsNumber() || index.GetNumberAsInt() < 0 || size_t(index.GetNumberAsInt()) >= g.model.lights.size())
    fail(g, cat("node ", v.node, ": ", kLights, " light does not exist"));
  const tinygltf::Light& src = g.model.lights[size_t(index.GetNumberAsInt())];
  PunctualLight l;
  if (src.type == "directional") l.type = PunctualLight::Type::Directional;
  else if (src.type == "point") l.type = PunctualLight::Type::Point;
  else if (src.type == "spot") l.type = PunctualLight::Type::Spot;
  else {
    warnings.push_back(cat(g.path, ": node ", v.node, ": skipping light of unknown type '", src.type, "'"));
    return std::nullopt;
  }
  l.name = !src.name.empty() ? src.name : n.name;
  l.node = v.node;
  if (src.color.size() == 3) l.color = glm::vec3(src.color[0], src.color[1], src.color[2]);
  l.intensity = static_cast<float>(src.intensity);
  l.range = static_cast<float>(src.range);
  l.position = glm::vec3(v.world * glm::dvec4(0, 0, 0, 1));
  l.direction = unitOr(glm::dmat3(v.world) * glm::dvec3(0, 0, -1), glm::vec3(0, 0, -1));
  l.innerConeAngle = static_cast<float>(src.spot.innerConeAngle);
  l.outerConeAngle = static_cast<float>(src.spot.outerConeAngle);
  for (float x : {l.color.r, l.color.g, l.color.b, l.intensity, l.range, l.innerConeAngle, l.outerConeAngle})
    if (!std::isfinite(x)) fail(g, cat("light ", index.GetNumberAsInt(), ": a parameter is not finite"));
  return l;
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
    if (it == cache.end())
      it = cache.emplace(key, readPrimitive(g, materials, n.mesh, int(p), scene.warnings)).first;
    if (it->second.skipped) continue;
    scene.meshes.push_back(makeInstance(g, v, n.mesh, int(p), it->second, scene.warnings));
  }
}

/// One band count for the whole file: every primitive with transfer has the same, and the
/// bake record, if any, says that count too.
void checkTransferBands(const Gltf& g, const std::map<std::pair<int, int>, PrimitiveData>& primitives,
                        Scene& scene) {
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

// ---------------------------------------------------------------------------------------------
// Nodes and animations (the renderer moves receivers with them; the bake is static)

/// Every node of the file with its parent and rest TRS (or matrix). Values were validated by
/// localTransform for the nodes of the default scene; others keep identity parts where a
/// property is malformed (they place nothing).
void readNodes(const Gltf& g, Scene& scene) {
  const auto& nodes = g.model.nodes;
  scene.nodes.assign(nodes.size(), Node{});
  for (size_t i = 0; i < nodes.size(); ++i) {
    const tinygltf::Node& n = nodes[i];
    Node& out = scene.nodes[i];
    out.name = n.name;
    if (n.matrix.size() == 16) {
      out.hasMatrix = true;
      out.matrix = glm::make_mat4(n.matrix.data());
    }
    if (n.translation.size() == 3) out.translation = glm::make_vec3(n.translation.data());
    if (n.rotation.size() == 4) {
      const glm::dvec4 q = glm::make_vec4(n.rotation.data());
      if (glm::length(q) > 0.0) out.rotation = q / glm::length(q);
    }
    if (n.scale.size() == 3) out.scale = glm::make_vec3(n.scale.data());
    for (int c : n.children)
      if (c >= 0 && size_t(c) < nodes.size()) scene.nodes[size_t(c)].parent = int(i);
  }
}

/// Reads and validates one channel; false if it is skipped (with a warning).
bool readChannel(const Gltf& g, const tinygltf::Animation& anim, const tinygltf::AnimationChannel& ch,
                 const std::string& where, AnimationChannel& out, std::vector<std::string>& warnings) {
  const tinygltf::Model& m = g.model;
  if (ch.target_node < 0) {
    warnings.push_back(cat(g.path, ": ", where, ": no target node, ignored"));
    return false;
  }
  if (size_t(ch.target_node) >= m.nodes.size())
    fail(g, cat(where, ": target node ", ch.target_node, " does not exist (the file has ", m.nodes.size(), ")"));
  out.node = ch.target_node;
  if (ch.target_path == "translation") {
    out.path = AnimationPath::Translation;
  } else if (ch.target_path == "rotation") {
    out.path = AnimationPath::Rotation;
  } else if (ch.target_path == "scale") {
    out.path = AnimationPath::Scale;
  } else if (ch.target_path == "weights") {
    warnings.push_back(cat(g.path, ": ", where, ": morph target weights are not supported, ignored"));
    return false;
  } else {
    fail(g, cat(where, ": unknown target path '", ch.target_path, "'"));
  }
  if (!m.nodes[size_t(out.node)].matrix.empty())
    fail(g, cat(where, ": node ", out.node, " has a matrix; glTF animates only nodes given as TRS"));
  if (ch.sampler < 0 || size_t(ch.sampler) >= anim.samplers.size())
    fail(g, cat(where, ": sampler ", ch.sampler, " does not exist (the animation has ", anim.samplers.size(), ")"));
  const tinygltf::AnimationSampler& s = anim.samplers[size_t(ch.sampler)];
  if (s.interpolation == "LINEAR" || s.interpolation.empty()) {
    out.interpolation = Interpolation::Linear;
  } else if (s.interpolation == "STEP") {
    out.interpolation = Interpolation::Step;
  } else if (s.interpolation == "CUBICSPLINE") {
    out.interpolation = Interpolation::CubicSpline;
  } else {
    fail(g, cat(where, ": unknown interpolation '", s.interpolation, "'"));
  }

  const std::string inWhere = cat(where, " / input");
  const AccessorData in = openAccessor(g, s.input, inWhere);
  if (in.components != 1 || in.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
    fail(g, cat(inWhere, ": key times must be SCALAR float, accessor ", s.input, " is ",
                typeName(in.components == 1 ? TINYGLTF_TYPE_SCALAR : in.components), " of component type ",
                in.componentType));
  const size_t keys = in.count;
  const bool cubic = out.interpolation == Interpolation::CubicSpline;
  if (keys < (cubic ? 2u : 1u))
    fail(g, cat(inWhere, ": ", keys, " key times, ", cubic ? "CUBICSPLINE needs at least 2" : "expected at least 1"));
  out.times.resize(keys);
  for (size_t k = 0; k < keys; ++k) {
    out.times[k] = in.get(k, 0);
    if (!std::isfinite(out.times[k])) fail(g, cat(inWhere, ": key time ", k, " is not finite"));
    if (k > 0 && !(out.times[k] > out.times[k - 1]))
      fail(g, cat(inWhere, ": key times not strictly increasing (key ", k, " at ", out.times[k], " s after ",
                  out.times[k - 1], " s)"));
  }

  const std::string outWhere = cat(where, " / output");
  const AccessorData val = openAccessor(g, s.output, outWhere);
  const bool rotation = out.path == AnimationPath::Rotation;
  const int want = rotation ? 4 : 3;
  const bool floatType = val.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT;
  // glTF allows normalized byte and short quaternions; translation and scale are float only.
  const bool normalizedRotation = rotation && val.normalized && val.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  if (val.components != want || !(floatType || normalizedRotation))
    fail(g, cat(outWhere, ": ", pathName(out.path), " values must be ", rotation ? "VEC4" : "VEC3",
                rotation ? " float or normalized integers" : " float", ", accessor ", s.output, " has ",
                val.components, " components of component type ", val.componentType,
                val.normalized ? " (normalized)" : ""));
  const size_t expected = keys * (cubic ? 3 : 1);
  if (val.count != expected)
    fail(g, cat(outWhere, ": ", val.count, " values, expected ", expected, " (", keys, " key times",
                cubic ? " × 3 for CUBICSPLINE: in-tangent, value, out-tangent" : "", ")"));
  out.values.resize(expected);
  for (size_t i = 0; i < expected; ++i) {
    glm::dvec4 v(0.0);
    for (int c = 0; c < want; ++c) v[c] = val.get(i, c);
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z) || !std::isfinite(v.w))
      fail(g, cat(outWhere, ": value ", i, " is not finite"));
    const bool isValue = !cubic || i % 3 == 1;  // tangents may be anything finite
    if (rotation && isValue && glm::length(v) == 0.0)
      fail(g, cat(outWhere, ": value ", i, " is a zero quaternion"));
    out.values[i] = v;
  }
  return true;
}

void readAnimations(const Gltf& g, Scene& scene) {
  const tinygltf::Model& m = g.model;
  for (size_t a = 0; a < m.animations.size(); ++a) {
    const tinygltf::Animation& anim = m.animations[a];
    Animation out;
    out.name = anim.name;
    const std::string animWhere = cat("animation ", a, anim.name.empty() ? "" : cat(" '", anim.name, "'"));
    std::set<std::pair<int, int>> targets;
    for (size_t c = 0; c < anim.channels.size(); ++c) {
      const tinygltf::AnimationChannel& ch = anim.channels[c];
      const int node = ch.target_node;
      std::string nodeName = node >= 0 && size_t(node) < m.nodes.size() && !m.nodes[size_t(node)].name.empty()
                                 ? cat(" '", m.nodes[size_t(node)].name, "'")
                                 : std::string();
      const std::string where = cat(animWhere, " / channel ", c, " (node ", node, nodeName, " ", ch.target_path, ")");
      AnimationChannel channel;
      if (!readChannel(g, anim, ch, where, channel, scene.warnings)) continue;
      // The spec: within one animation, each node property is the target of one channel only.
      if (!targets.insert({channel.node, int(channel.path)}).second)
        fail(g, cat(where, ": a second channel of this animation targets the same node property"));
      out.channels.push_back(std::move(channel));
    }
    scene.animations.push_back(std::move(out));
  }
}

/// The bake is static: an instance that moves can be neither baked nor an occluder of the bake
/// (its shadow would stay where it was at rest), so every animated instance becomes a receiver,
/// except under an explicit {"prt": {"receiver": false}}, which keeps it baked in its rest pose
/// (with a warning: the renderer then draws it there).
void makeAnimatedInstancesReceivers(const Gltf& g, Scene& scene, const std::vector<char>& keepStatic) {
  std::set<int> warned;
  for (MeshInstance& inst : scene.meshes) {
    if (inst.receiverOnly || !isAnimated(scene, inst.node)) continue;
    if (!keepStatic[size_t(inst.node)]) {
      inst.receiverOnly = true;
      inst.receiverReason = ReceiverReason::Animated;
    } else if (warned.insert(inst.node).second) {
      scene.warnings.push_back(cat(g.path, ": ", nodeLabel(scene, inst.node),
                                   " is animated but marked static (extras prt.receiver = false): baked in its "
                                   "rest pose, its animation is ignored"));
    }
  }
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
  Traversal traversal{g, marks, std::vector<char>(g.model.nodes.size(), 0),
                      std::vector<char>(g.model.nodes.size(), 0), {}};
  for (int root : rootNodes(g)) traversal.visit(root, NodeVisit{}, 0);
  std::map<std::pair<int, int>, PrimitiveData> cache;
  std::vector<char> keepStatic(g.model.nodes.size(), 0);  // inherited, per node of the default scene
  for (const NodeVisit& v : traversal.out) {
    addNodeContents(g, v, materials, scene, cache);
    keepStatic[size_t(v.node)] = v.keepStatic;
  }
  decodeUsedTextures(g, materials, scene);
  readBakeRecord(g, scene);
  checkTransferBands(g, cache, scene);
  computeBounds(g, scene);
  readNodes(g, scene);
  readAnimations(g, scene);
  makeAnimatedInstancesReceivers(g, scene, keepStatic);
  takeBandsFromRecord(scene);
  return scene;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Public: loading

Scene loadScene(const std::string& path, const LoadOptions& options) {
  return loadSceneFrom(path, nullptr, options);
}

Scene loadSceneFromMemory(const std::string& name, const std::string& bytes, const LoadOptions& options) {
  return loadSceneFrom(name, &bytes, options);
}

}  // namespace prt
