// KHR_draco_mesh_compression and EXT_meshopt_compression decoded into an ordinary glTF document
// (gltf_decode.h). Every number taken from the document is checked before it sizes or indexes
// anything, and the size of what a meshopt stream may decode to is bounded by the size of the
// stream: these paths see untrusted bytes and are fuzzed (tests/fuzz/fuzz_gltf.cpp).
#include "gltf_decode.h"

#include <draco/compression/decode.h>
#include <draco/core/decoder_buffer.h>
#include <draco/mesh/mesh.h>
#include <meshoptimizer.h>

#include <cstdint>
#include <cstring>
#include <limits>
#include <set>
#include <vector>

#include <nlohmann/json.hpp>

#include "prt/error.h"
#include "prt/scene.h"

namespace prt::gltf {

namespace {

using Json = nlohmann::json;
using Bytes = std::vector<unsigned char>;

// glTF component types (the numbers of the specification; tinygltf's constants are not seen here).
constexpr int kByte = 5120, kUnsignedByte = 5121, kShort = 5122, kUnsignedShort = 5123, kUnsignedInt = 5125,
              kFloat = 5126;
// The vertex codec spends at least 2 bits on 16 bytes of output (a block of zeros), a ratio of
// 64; the index codecs at least a byte per triangle or index. Decoded sizes beyond 64 × the
// stream (+ a block) cannot come from a valid stream and are refused before allocating.
constexpr uint64_t kMaxMeshoptRatio = 64;
constexpr uint64_t kMeshoptSlack = 1 << 16;

struct Document {
  const std::string& path;
  Json json;
  std::vector<std::optional<Bytes>> buffers;  // empty optional: a meshopt fallback buffer (no data)
  std::string bin;                            // the output buffer
};

[[noreturn]] void fail(const Document& d, const std::string& what) { throw Error(cat(d.path, ": ", what)); }

/// A non-negative integer member of `object` (`fallback` when absent).
uint64_t count(const Document& d, const Json& object, const char* key, const std::string& where,
               std::optional<uint64_t> fallback = std::nullopt) {
  auto it = object.find(key);
  if (it == object.end()) {
    if (!fallback) fail(d, cat(where, ": ", key, " is missing"));
    return *fallback;
  }
  if (it->is_number_unsigned()) return it->get<uint64_t>();
  if (it->is_number_integer() && it->get<int64_t>() >= 0) return uint64_t(it->get<int64_t>());
  fail(d, cat(where, ": ", key, " is not a non-negative integer"));
}

Json* member(Json& object, const char* key) {
  if (!object.is_object()) return nullptr;
  auto it = object.find(key);
  return it == object.end() ? nullptr : &*it;
}

/// The array `key` of the document's top level (empty if absent); refuses a non-array.
Json& topArray(Document& d, const char* key) {
  Json* a = member(d.json, key);
  if (!a) {
    d.json[key] = Json::array();
    return d.json[key];
  }
  if (!a->is_array()) fail(d, cat(key, " is not an array"));
  return *a;
}

void padBin(std::string& bin) {
  while (bin.size() % 4) bin.push_back('\0');
}

/// Appends `bytes` to the output buffer as a new buffer view; returns its index.
int appendView(Document& d, const void* bytes, size_t size) {
  padBin(d.bin);
  if (size > kMaxFileBytes - d.bin.size()) fail(d, cat("decoded geometry exceeds ", kMaxFileBytes, " bytes"));
  Json view = {{"buffer", 0}, {"byteOffset", d.bin.size()}, {"byteLength", size}};
  d.bin.append(static_cast<const char*>(bytes), size);
  Json& views = topArray(d, "bufferViews");
  views.push_back(std::move(view));
  return int(views.size() - 1);
}

// ---------------------------------------------------------------------------------------------
// Buffers

std::optional<Bytes> base64(const std::string& text) {
  auto value = [](unsigned char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+' || c == '-') return 62;
    if (c == '/' || c == '_') return 63;
    return -1;
  };
  Bytes out;
  out.reserve(text.size() / 4 * 3);
  uint32_t acc = 0;
  int bits = 0;
  for (unsigned char c : text) {
    if (c == '=') break;
    int v = value(c);
    if (v < 0) return std::nullopt;
    acc = (acc << 6) | uint32_t(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<unsigned char>(acc >> bits));
    }
  }
  return out;
}

/// The BIN chunk of a GLB (nothing if it has none or is malformed: tinygltf reports that).
std::optional<Bytes> glbBin(const std::string& bytes) {
  if (bytes.size() < 20) return std::nullopt;
  uint32_t jsonLength = 0;
  std::memcpy(&jsonLength, bytes.data() + 12, 4);
  size_t at = 20 + size_t(jsonLength);
  if (jsonLength > bytes.size() - 20 || bytes.size() - at < 8 || std::memcmp(bytes.data() + at + 4, "BIN\0", 4) != 0)
    return std::nullopt;
  uint32_t binLength = 0;
  std::memcpy(&binLength, bytes.data() + at, 4);
  if (binLength > bytes.size() - at - 8) return std::nullopt;
  return Bytes(bytes.begin() + std::ptrdiff_t(at + 8), bytes.begin() + std::ptrdiff_t(at + 8 + binLength));
}

/// A buffer's bytes from a data: URI or a file beside the document (through the URI guard, as
/// tinygltf would read it).
Bytes readUri(const Document& d, const std::string& uri, const std::string& where, UriGuard& guard) {
  if (uri.rfind("data:", 0) == 0) {
    size_t comma = uri.find(";base64,");
    std::optional<Bytes> out = comma == std::string::npos ? std::nullopt : base64(uri.substr(comma + 8));
    if (!out) fail(d, cat(where, ": the data: URI is not base64"));
    return *out;
  }
  std::string joined =
      guard.baseDir.empty() || guard.baseDir.back() == '/' ? guard.baseDir + uri : cat(guard.baseDir, "/", uri);
  std::string file = guardedExpandFilePath(joined, &guard);
  if (!guardedFileExists(file, &guard)) {
    if (!guard.refusal.empty()) {
      if (guard.refusalIsExternal) throw ExternalUriRefused(cat(d.path, ": ", guard.refusal));
      fail(d, guard.refusal);
    }
    fail(d, cat(where, ": file '", uri, "' not found"));
  }
  Bytes out;
  std::string err;
  if (!guardedReadWholeFile(&out, &err, file, &guard)) fail(d, cat(where, ": file '", uri, "': ", err));
  return out;
}

bool isFallback(const Json& buffer) {
  const Json* ext = member(const_cast<Json&>(buffer), "extensions");
  const Json* meshopt = ext ? member(const_cast<Json&>(*ext), kMeshopt) : nullptr;
  return meshopt && meshopt->is_object() && meshopt->value("fallback", false) == true;
}

void readBuffers(Document& d, const std::string& bytes, bool binary, UriGuard& guard) {
  Json& buffers = topArray(d, "buffers");
  for (size_t i = 0; i < buffers.size(); ++i) {
    const Json& b = buffers[i];
    const std::string where = cat("buffer ", i);
    if (!b.is_object()) fail(d, cat(where, " is not an object"));
    auto uri = b.find("uri");
    if (uri != b.end()) {
      if (!uri->is_string()) fail(d, cat(where, ": uri is not a string"));
      d.buffers.emplace_back(readUri(d, uri->get<std::string>(), where, guard));
    } else if (binary && i == 0) {
      std::optional<Bytes> bin = glbBin(bytes);
      if (!bin) fail(d, cat(where, ": the GLB has no BIN chunk"));
      d.buffers.emplace_back(std::move(bin));
    } else if (isFallback(b)) {
      d.buffers.emplace_back(std::nullopt);
    } else {
      fail(d, cat(where, " has no uri and is not the GLB's BIN chunk"));
    }
    if (d.buffers.back() && count(d, b, "byteLength", where) > d.buffers.back()->size())
      fail(d, cat(where, ": byteLength ", count(d, b, "byteLength", where), " but ", d.buffers.back()->size(),
                  " bytes of data"));
  }
}

/// Bytes [offset, offset + length) of buffer `index`, checked.
const unsigned char* bufferRange(const Document& d, uint64_t index, uint64_t offset, uint64_t length,
                                 const std::string& where) {
  if (index >= d.buffers.size()) fail(d, cat(where, ": buffer ", index, " does not exist"));
  if (!d.buffers[index])
    fail(d, cat(where, ": buffer ", index, " is the meshopt fallback buffer, which holds no data"));
  const Bytes& b = *d.buffers[index];
  if (offset > b.size() || length > b.size() - offset)
    fail(d, cat(where, ": bytes ", offset, "..", offset + length, " run past the end of buffer ", index, " (", b.size(),
                " bytes)"));
  return b.data() + offset;
}

// ---------------------------------------------------------------------------------------------
// EXT_meshopt_compression

std::vector<unsigned char> decodeMeshoptView(const Document& d, const Json& ext, const std::string& where) {
  if (!ext.is_object()) fail(d, cat(where, ": ", kMeshopt, " is not an object"));
  const uint64_t buffer = count(d, ext, "buffer", where);
  const uint64_t offset = count(d, ext, "byteOffset", where, 0);
  const uint64_t length = count(d, ext, "byteLength", where);
  const uint64_t stride = count(d, ext, "byteStride", where);
  const uint64_t n = count(d, ext, "count", where);
  const std::string mode = ext.value("mode", std::string());
  const std::string filter = ext.value("filter", std::string("NONE"));
  const unsigned char* src = bufferRange(d, buffer, offset, length, where);
  const std::string meshopt = cat(where, ": ", kMeshopt);
  if (mode == "ATTRIBUTES") {
    if (stride == 0 || stride % 4 != 0 || stride > 256)
      fail(d, cat(meshopt, ": byteStride ", stride, " (ATTRIBUTES needs a multiple of 4 up to 256)"));
  } else if (mode == "TRIANGLES" || mode == "INDICES") {
    if (stride != 2 && stride != 4) fail(d, cat(meshopt, ": byteStride ", stride, " (", mode, " needs 2 or 4)"));
    if (mode == "TRIANGLES" && n % 3 != 0) fail(d, cat(meshopt, ": count ", n, " is not a multiple of 3"));
  } else {
    fail(d, cat(meshopt, ": unknown mode '", mode, "'"));
  }
  if (filter != "NONE") {
    bool ok = mode == "ATTRIBUTES" && ((filter == "OCTAHEDRAL" && (stride == 4 || stride == 8)) ||
                                       (filter == "QUATERNION" && stride == 8) || filter == "EXPONENTIAL");
    if (!ok) fail(d, cat(meshopt, ": filter '", filter, "' does not apply to mode ", mode, ", byteStride ", stride));
  }
  if (n > (kMaxMeshoptRatio * length + kMeshoptSlack) / stride)
    fail(d, cat(meshopt, ": ", n, " elements of ", stride, " bytes cannot come from a ", length, "-byte stream"));
  std::vector<unsigned char> out(n * stride);
  int rc = mode == "ATTRIBUTES"  ? meshopt_decodeVertexBuffer(out.data(), n, stride, src, length)
           : mode == "TRIANGLES" ? meshopt_decodeIndexBuffer(out.data(), n, stride, src, length)
                                 : meshopt_decodeIndexSequence(out.data(), n, stride, src, length);
  if (rc != 0) fail(d, cat(meshopt, ": corrupt ", mode, " stream (meshopt error ", rc, ")"));
  if (filter == "OCTAHEDRAL") meshopt_decodeFilterOct(out.data(), n, stride);
  if (filter == "QUATERNION") meshopt_decodeFilterQuat(out.data(), n, stride);
  if (filter == "EXPONENTIAL") meshopt_decodeFilterExp(out.data(), n, stride);
  return out;
}

/// Every buffer view rebased onto the output buffer; meshopt ones decoded into it.
void rebaseViews(Document& d) {
  std::vector<uint64_t> base(d.buffers.size(), 0);
  for (size_t i = 0; i < d.buffers.size(); ++i) {
    if (!d.buffers[i]) continue;
    padBin(d.bin);
    base[i] = d.bin.size();
    d.bin.append(reinterpret_cast<const char*>(d.buffers[i]->data()), d.buffers[i]->size());
  }
  Json& views = topArray(d, "bufferViews");
  for (size_t v = 0; v < views.size(); ++v) {
    Json& view = views[v];
    const std::string where = cat("buffer view ", v);
    if (!view.is_object()) fail(d, cat(where, " is not an object"));
    Json* ext = member(view, "extensions");
    Json* meshopt = ext ? member(*ext, kMeshopt) : nullptr;
    if (meshopt) {
      std::vector<unsigned char> data = decodeMeshoptView(d, *meshopt, where);
      padBin(d.bin);
      if (data.size() > kMaxFileBytes - d.bin.size())
        fail(d, cat("decoded geometry exceeds ", kMaxFileBytes, " bytes"));
      view["byteOffset"] = d.bin.size();
      view["byteLength"] = data.size();
      view["buffer"] = 0;
      d.bin.append(reinterpret_cast<const char*>(data.data()), data.size());
      ext->erase(kMeshopt);
      if (ext->empty()) view.erase("extensions");
      continue;
    }
    const uint64_t buffer = count(d, view, "buffer", where);
    const uint64_t offset = count(d, view, "byteOffset", where, 0);
    bufferRange(d, buffer, offset, count(d, view, "byteLength", where), where);
    view["buffer"] = 0;
    view["byteOffset"] = base[buffer] + offset;
  }
}

// ---------------------------------------------------------------------------------------------
// KHR_draco_mesh_compression

int componentBytes(int type) {
  switch (type) {
    case kByte:
    case kUnsignedByte:
      return 1;
    case kShort:
    case kUnsignedShort:
      return 2;
    case kUnsignedInt:
    case kFloat:
      return 4;
    default:
      return 0;
  }
}

int typeComponents(const std::string& type) {
  if (type == "SCALAR") return 1;
  if (type == "VEC2") return 2;
  if (type == "VEC3") return 3;
  if (type == "VEC4") return 4;
  return 0;
}

template <class T>
bool convertAttribute(const draco::PointAttribute& attr, size_t points, int components,
                      std::vector<unsigned char>& out) {
  out.resize(points * size_t(components) * sizeof(T));
  std::vector<T> value(static_cast<size_t>(components));
  for (size_t i = 0; i < points; ++i) {
    if (!attr.ConvertValue<T>(attr.mapped_index(draco::PointIndex(uint32_t(i))), int8_t(components), value.data()))
      return false;
    std::memcpy(out.data() + i * value.size() * sizeof(T), value.data(), value.size() * sizeof(T));
  }
  return true;
}

/// Points accessor `index` of a decoded primitive at new data. An accessor shared with another
/// Draco primitive is copied first, so each keeps its own decoded values.
void setAccessor(Document& d, Json& slot, int view, size_t elements, std::optional<int> componentType,
                 std::set<uint64_t>& decoded, const std::string& where) {
  Json& accessors = topArray(d, "accessors");
  if (!slot.is_number_unsigned() && !(slot.is_number_integer() && slot.get<int64_t>() >= 0))
    fail(d, cat(where, ": accessor is not a non-negative integer"));
  uint64_t index = slot.get<uint64_t>();
  if (index >= accessors.size() || !accessors[index].is_object())
    fail(d, cat(where, ": accessor ", index, " does not exist"));
  if (!decoded.insert(index).second) {
    accessors.push_back(accessors[index]);
    index = accessors.size() - 1;
    slot = index;
    decoded.insert(index);
  }
  Json& a = accessors[index];
  a["bufferView"] = view;
  a["byteOffset"] = 0;
  a["count"] = elements;
  if (componentType) a["componentType"] = *componentType;
  a.erase("sparse");
}

// convertAttribute for the accessor's component type `type` (float for any other).
bool convertAttributeAs(int type, const draco::PointAttribute& attr, size_t points, int components,
                        std::vector<unsigned char>& data) {
  switch (type) {
    case kByte:
      return convertAttribute<int8_t>(attr, points, components, data);
    case kUnsignedByte:
      return convertAttribute<uint8_t>(attr, points, components, data);
    case kShort:
      return convertAttribute<int16_t>(attr, points, components, data);
    case kUnsignedShort:
      return convertAttribute<uint16_t>(attr, points, components, data);
    case kUnsignedInt:
      return convertAttribute<uint32_t>(attr, points, components, data);
    default:
      return convertAttribute<float>(attr, points, components, data);
  }
}

void decodeDracoPrimitive(Document& d, Json& prim, Json& ext, std::set<uint64_t>& decoded, const std::string& where) {
  const std::string draco = cat(where, ": ", kDraco);
  if (!ext.is_object()) fail(d, cat(draco, " is not an object"));
  const uint64_t viewIndex = count(d, ext, "bufferView", draco);
  Json& views = topArray(d, "bufferViews");
  if (viewIndex >= views.size()) fail(d, cat(draco, ": buffer view ", viewIndex, " does not exist"));
  // Views are rebased already: all of them lie in the output buffer.
  const uint64_t offset = count(d, views[viewIndex], "byteOffset", draco, 0);
  const uint64_t length = count(d, views[viewIndex], "byteLength", draco);
  if (offset > d.bin.size() || length > d.bin.size() - offset)
    fail(d, cat(draco, ": buffer view ", viewIndex, " runs past the end of its buffer"));
  draco::DecoderBuffer stream;
  stream.Init(d.bin.data() + offset, size_t(length));
  draco::Decoder decoder;
  auto result = decoder.DecodePointCloudFromBuffer(&stream);
  if (!result.ok()) fail(d, cat(draco, ": corrupt Draco stream (", result.status().error_msg_string(), ")"));
  std::unique_ptr<draco::PointCloud> cloud = std::move(result).value();
  const size_t points = cloud->num_points();

  Json* attributes = member(ext, "attributes");
  Json* primAttributes = member(prim, "attributes");
  if (!attributes || !attributes->is_object() || !primAttributes || !primAttributes->is_object())
    fail(d, cat(draco, ": attributes missing"));
  // Decoded into new views first: appending to the output buffer may move d.bin's bytes.
  Json& accessors = topArray(d, "accessors");
  for (auto& [name, id] : attributes->items()) {
    const std::string here = cat(draco, " / ", name);
    Json* slot = member(*primAttributes, name.c_str());
    if (!slot) fail(d, cat(here, ": the primitive has no such attribute"));
    if (!id.is_number_unsigned() && !(id.is_number_integer() && id.get<int64_t>() >= 0))
      fail(d, cat(here, ": attribute id is not a non-negative integer"));
    const draco::PointAttribute* attr = cloud->GetAttributeByUniqueId(id.get<uint32_t>());
    if (!attr) fail(d, cat(here, ": the Draco stream has no attribute ", id.get<uint64_t>()));
    uint64_t index = slot->is_number_unsigned() ? slot->get<uint64_t>() : std::numeric_limits<uint64_t>::max();
    if (index >= accessors.size() || !accessors[index].is_object()) fail(d, cat(here, ": accessor does not exist"));
    const Json& a = accessors[index];
    const int components = typeComponents(a.value("type", std::string()));
    const int type = a.value("componentType", 0);
    if (components == 0 || componentBytes(type) == 0)
      fail(d, cat(here, ": accessor ", index, " has an unsupported type or component type"));
    std::vector<unsigned char> data;
    if (!convertAttributeAs(type, *attr, points, components, data))
      fail(d, cat(here, ": the Draco attribute cannot be read as accessor ", index, " declares it"));
    int view = appendView(d, data.data(), data.size());
    setAccessor(d, *slot, view, points, std::nullopt, decoded, here);
  }
  if (const auto* mesh = dynamic_cast<const draco::Mesh*>(cloud.get()); mesh && mesh->num_faces() > 0) {
    std::vector<uint32_t> indices;
    indices.reserve(size_t(mesh->num_faces()) * 3);
    for (draco::FaceIndex f(0); f < mesh->num_faces(); ++f)
      for (int k = 0; k < 3; ++k) indices.push_back(mesh->face(f)[k].value());
    int view = appendView(d, indices.data(), indices.size() * sizeof(uint32_t));
    if (!prim.contains("indices")) {
      topArray(d, "accessors").push_back({{"componentType", kUnsignedInt}, {"type", "SCALAR"}});
      prim["indices"] = topArray(d, "accessors").size() - 1;
    }
    setAccessor(d, prim["indices"], view, indices.size(), kUnsignedInt, decoded, cat(draco, " / indices"));
    prim["mode"] = 4;  // Draco's faces are a triangle list, whatever the strip the mode named
  }
  Json& extensions = prim["extensions"];
  extensions.erase(kDraco);
  if (extensions.empty()) prim.erase("extensions");
}

void decodeDraco(Document& d) {
  Json& meshes = topArray(d, "meshes");
  std::set<uint64_t> decoded;
  for (size_t m = 0; m < meshes.size(); ++m) {
    Json* prims = member(meshes[m], "primitives");
    if (!prims || !prims->is_array()) continue;
    for (size_t p = 0; p < prims->size(); ++p) {
      Json& prim = (*prims)[p];
      Json* ext = member(prim, "extensions");
      Json* draco = ext ? member(*ext, kDraco) : nullptr;
      if (draco) decodeDracoPrimitive(d, prim, *draco, decoded, cat("mesh ", m, " / primitive ", p));
    }
  }
}

void dropExtensionNames(Document& d) {
  for (const char* list : {"extensionsUsed", "extensionsRequired"}) {
    Json* names = member(d.json, list);
    if (!names || !names->is_array()) continue;
    Json kept = Json::array();
    for (const Json& n : *names)
      if (!(n.is_string() && (n == kDraco || n == kMeshopt))) kept.push_back(n);
    if (kept.empty())
      d.json.erase(list);
    else
      *names = std::move(kept);
  }
}

void putU32(std::string& out, uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); }

std::string toGlb(Document& d) {
  padBin(d.bin);
  d.json["buffers"] = d.bin.empty() ? Json::array() : Json::array({{{"byteLength", d.bin.size()}}});
  std::string text = d.json.dump();
  while (text.size() % 4) text.push_back(' ');
  const uint64_t total = 12 + 8 + uint64_t(text.size()) + (d.bin.empty() ? 0 : 8 + uint64_t(d.bin.size()));
  if (total > kMaxFileBytes) fail(d, cat("decoded file exceeds ", kMaxFileBytes, " bytes"));
  std::string out;
  out.reserve(size_t(total));
  out.append("glTF", 4);
  putU32(out, 2);
  putU32(out, uint32_t(total));
  putU32(out, uint32_t(text.size()));
  out.append("JSON", 4);
  out += text;
  if (!d.bin.empty()) {
    putU32(out, uint32_t(d.bin.size()));
    out.append("BIN\0", 4);
    out += d.bin;
  }
  return out;
}

std::string jsonChunk(const std::string& bytes, bool binary) {
  if (!binary) return bytes;
  if (bytes.size() < 20 || std::memcmp(bytes.data() + 16, "JSON", 4) != 0) return "";
  uint32_t length = 0;
  std::memcpy(&length, bytes.data() + 12, 4);
  return length <= bytes.size() - 20 ? bytes.substr(20, length) : "";
}

}  // namespace

// WebP images given as data: URIs, which tinygltf 2.7 refuses ("unknown image type"), become
// buffer views of the output buffer holding their bytes, as a .glb would hold them.
constexpr const char* kWebpDataUri = "data:image/webp;base64,";

void embedWebpDataImages(Document& d) {
  Json* images = member(d.json, "images");
  if (!images || !images->is_array()) return;
  for (size_t i = 0; i < images->size(); ++i) {
    Json& image = (*images)[i];
    Json* uri = member(image, "uri");
    if (!uri || !uri->is_string()) continue;
    const std::string& text = uri->get_ref<const std::string&>();
    if (text.rfind(kWebpDataUri, 0) != 0) continue;
    const std::optional<Bytes> bytes = base64(text.substr(std::strlen(kWebpDataUri)));
    if (!bytes) fail(d, cat("image ", i, ": the data: URI is not base64"));
    const int view = appendView(d, bytes->data(), bytes->size());
    image.erase("uri");
    image["bufferView"] = view;
    image["mimeType"] = "image/webp";
  }
}

std::optional<std::string> decodeCompressed(const std::string& path, const std::string& bytes, bool binary,
                                            UriGuard& guard) {
  std::string text = jsonChunk(bytes, binary);
  if (text.find(kDraco) == std::string::npos && text.find(kMeshopt) == std::string::npos &&
      text.find(kWebpDataUri) == std::string::npos)
    return std::nullopt;
  Document d{path, Json::parse(text, nullptr, false), {}, {}};
  if (d.json.is_discarded() || !d.json.is_object()) return std::nullopt;  // tinygltf reports the syntax
  try {
    readBuffers(d, bytes, binary, guard);
    rebaseViews(d);
    decodeDraco(d);
    embedWebpDataImages(d);
    dropExtensionNames(d);
    return toGlb(d);
  } catch (const Json::exception& e) {
    // A member of an unexpected JSON type (a string where a number belongs, say).
    fail(d, cat("malformed ", kDraco, ", ", kMeshopt, " or WebP data: image (", e.what(), ")"));
  }
}

}  // namespace prt::gltf
