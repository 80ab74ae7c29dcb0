// The container the writers' edited model goes into (gltf_glb.h): images embedded with their
// original encoded bytes, every buffer view still referred to packed into one buffer, accessor
// bounds made exact, and the file written atomically as a .glb (or as .gltf JSON with a data:
// URI) that the Khronos glTF Validator accepts.
#include "gltf_glb.h"
#include "gltf_operator.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "prt/atomic_file.h"
#include "prt/error.h"

namespace prt::gltf {

namespace fs = std::filesystem;
using Json = nlohmann::json;

int appendBufferView(tinygltf::Model& m, int buffer, const void* bytes, size_t size, int target) {
  std::vector<unsigned char>& data = m.buffers[size_t(buffer)].data;
  data.resize((data.size() + 3) / 4 * 4, 0);
  tinygltf::BufferView view;
  view.buffer = buffer;
  view.byteOffset = data.size();
  view.byteLength = size;
  view.target = target;
  const auto* p = static_cast<const unsigned char*>(bytes);
  data.insert(data.end(), p, p + size);
  m.bufferViews.push_back(view);
  return static_cast<int>(m.bufferViews.size() - 1);
}

int stagingBuffer(tinygltf::Model& m, int& staging) {
  if (staging < 0) {
    m.buffers.emplace_back();
    staging = static_cast<int>(m.buffers.size() - 1);
  }
  return staging;
}

namespace {

/// tinygltf image writer callback that writes nothing: the writers embed every image as a
/// buffer view first, and an image they could not read keeps its URI as it was.
bool keepImageUri(const std::string*, const std::string*, const tinygltf::Image*, bool, std::string*, void*) {
  return false;
}

std::string sniffMimeType(const std::vector<unsigned char>& b) {
  auto starts = [&](const char* magic, size_t n, size_t at = 0) {
    return b.size() >= at + n && std::memcmp(b.data() + at, magic, n) == 0;
  };
  if (starts("\x89PNG", 4)) return "image/png";
  if (starts("\xFF\xD8\xFF", 3)) return "image/jpeg";
  if (starts("RIFF", 4) && starts("WEBP", 4, 8)) return "image/webp";
  if (starts("\xABKTX 20\xBB", 8)) return "image/ktx2";
  return "";
}

/// Moves every image held by URI (file or data:) into a buffer view, with its original
/// encoded bytes: nothing is re-encoded, and the .glb is self-contained.
void embedImages(tinygltf::Model& m, int& staging) {
  for (tinygltf::Image& image : m.images) {
    if (image.bufferView >= 0 || image.image.empty()) continue;  // unreadable ones keep their URI
    std::string mime = sniffMimeType(image.image);
    if (mime.empty()) mime = image.mimeType;
    if (mime.empty()) continue;
    image.bufferView = appendBufferView(m, stagingBuffer(m, staging), image.image.data(), image.image.size(), 0);
    image.mimeType = mime;
    image.uri.clear();
    image.image.clear();
  }
}

/// True when every extension used is known not to refer to accessors or buffer views, so
/// unreferenced ones can be dropped without breaking an index hidden in an extension.
bool onlyKnownExtensions(const tinygltf::Model& m) {
  for (const std::string& e : m.extensionsUsed) {
    bool known = e.rfind("KHR_materials_", 0) == 0 || e == kLights || e == kTextureTransform ||
                 e == "KHR_mesh_quantization" || e == "KHR_texture_basisu" || e == "EXT_texture_webp";
    if (!known) return false;
  }
  return true;
}

/// Marks the accessors that core glTF objects refer to.
std::vector<char> usedAccessors(const tinygltf::Model& m) {
  std::vector<char> used(m.accessors.size(), 0);
  auto mark = [&](int a) {
    if (a >= 0 && size_t(a) < used.size()) used[size_t(a)] = 1;
  };
  for (const tinygltf::Mesh& mesh : m.meshes) {
    for (const tinygltf::Primitive& prim : mesh.primitives) {
      for (const auto& [name, a] : prim.attributes) mark(a);
      mark(prim.indices);
      for (const auto& target : prim.targets)
        for (const auto& [name, a] : target) mark(a);
    }
  }
  for (const tinygltf::Skin& skin : m.skins) mark(skin.inverseBindMatrices);
  for (const tinygltf::Animation& anim : m.animations)
    for (const tinygltf::AnimationSampler& s : anim.samplers) {
      mark(s.input);
      mark(s.output);
    }
  return used;
}

void remapAccessors(tinygltf::Model& m, const std::vector<char>& keep) {
  std::vector<int> to(m.accessors.size(), -1);
  std::vector<tinygltf::Accessor> kept;
  for (size_t i = 0; i < m.accessors.size(); ++i) {
    if (!keep[i]) continue;
    to[i] = static_cast<int>(kept.size());
    kept.push_back(std::move(m.accessors[i]));
  }
  m.accessors = std::move(kept);
  auto map = [&](int& a) {
    if (a >= 0 && size_t(a) < to.size()) a = to[size_t(a)];
  };
  for (tinygltf::Mesh& mesh : m.meshes) {
    for (tinygltf::Primitive& prim : mesh.primitives) {
      for (auto& [name, a] : prim.attributes) map(a);
      map(prim.indices);
      for (auto& target : prim.targets)
        for (auto& [name, a] : target) map(a);
    }
  }
  for (tinygltf::Skin& skin : m.skins) map(skin.inverseBindMatrices);
  for (tinygltf::Animation& anim : m.animations)
    for (tinygltf::AnimationSampler& s : anim.samplers) {
      map(s.input);
      map(s.output);
    }
}

/// GLB holds one binary buffer: copies every kept buffer view into a new buffer 0, dropping
/// views (and, with only known extensions, accessors) that nothing refers to any more —
/// a lit scene then no longer carries the transfer it was made from.
void packIntoOneBuffer(const Gltf& g, tinygltf::Model& m) {
  bool prune = onlyKnownExtensions(m);
  if (prune) remapAccessors(m, usedAccessors(m));
  std::vector<char> keepView(m.bufferViews.size(), prune ? 0 : 1);
  auto mark = [&](int v) {
    if (v >= 0 && size_t(v) < keepView.size()) keepView[size_t(v)] = 1;
  };
  for (const tinygltf::Accessor& a : m.accessors) {
    mark(a.bufferView);
    if (a.sparse.isSparse) {
      mark(a.sparse.indices.bufferView);
      mark(a.sparse.values.bufferView);
    }
  }
  for (const tinygltf::Image& image : m.images) mark(image.bufferView);
  mark(operatorBufferView(m));

  tinygltf::Buffer packed;
  std::vector<int> to(m.bufferViews.size(), -1);
  std::vector<tinygltf::BufferView> views;
  for (size_t i = 0; i < m.bufferViews.size(); ++i) {
    if (!keepView[i]) continue;
    tinygltf::BufferView view = m.bufferViews[i];
    if (view.buffer < 0 || size_t(view.buffer) >= m.buffers.size())
      fail(g, cat("buffer view ", i, " uses buffer ", view.buffer, ", which does not exist"));
    const std::vector<unsigned char>& src = m.buffers[size_t(view.buffer)].data;
    if (view.byteOffset > src.size() || view.byteLength > src.size() - view.byteOffset)
      fail(g, cat("buffer view ", i, " runs past the end of buffer ", view.buffer));
    // 4-byte alignment keeps every accessor's offset a multiple of its component size.
    packed.data.resize((packed.data.size() + 3) / 4 * 4, 0);
    size_t offset = packed.data.size();
    packed.data.insert(packed.data.end(), src.begin() + std::ptrdiff_t(view.byteOffset),
                       src.begin() + std::ptrdiff_t(view.byteOffset + view.byteLength));
    view.buffer = 0;
    view.byteOffset = offset;
    to[i] = static_cast<int>(views.size());
    views.push_back(std::move(view));
  }
  auto map = [&](int& v) {
    if (v >= 0 && size_t(v) < to.size()) v = to[size_t(v)];
  };
  for (tinygltf::Accessor& a : m.accessors) {
    map(a.bufferView);
    if (a.sparse.isSparse) {
      map(a.sparse.indices.bufferView);
      map(a.sparse.values.bufferView);
    }
  }
  for (tinygltf::Image& image : m.images) map(image.bufferView);
  if (int view = operatorBufferView(m); view >= 0) {
    map(view);
    setOperatorBufferView(m, view);
  }
  m.bufferViews = std::move(views);
  m.buffers.assign(1, std::move(packed));
}

/// glTF wants an accessor's min and max to be its values' exact bounds. Data decoded from Draco
/// keeps the bounds the file gave before (of the values before quantisation, of the indices
/// before Draco reordered the vertices): each declared bound of a float or plain integer
/// accessor that is not its data's (floats compared as floats) is replaced by the data's.
/// Normalised, sparse and unreadable accessors keep theirs.
void exactBounds(const Gltf& g, tinygltf::Model& m) {
  for (size_t i = 0; i < m.accessors.size(); ++i) {
    tinygltf::Accessor& a = m.accessors[i];
    const bool isFloat = a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT;
    if ((!isFloat && a.normalized) || a.sparse.isSparse || a.count == 0) continue;
    if (a.minValues.empty() && a.maxValues.empty()) continue;
    AccessorData d;
    try {
      d = openAccessor(g, int(i), cat("accessor ", i));
    } catch (const Error&) {
      continue;  // data the writer does not read (nothing of the scene uses it) keeps its bounds
    }
    std::vector<double> lo(size_t(d.components), std::numeric_limits<double>::infinity());
    std::vector<double> hi(size_t(d.components), -std::numeric_limits<double>::infinity());
    for (size_t v = 0; v < d.count; ++v)
      for (int c = 0; c < d.components; ++c) {
        lo[size_t(c)] = std::min(lo[size_t(c)], d.get(v, c));
        hi[size_t(c)] = std::max(hi[size_t(c)], d.get(v, c));
      }
    auto exact = [&](std::vector<double>& declared, const std::vector<double>& actual) {
      if (declared.size() != actual.size()) return;  // left as it is (the reader checks components)
      for (size_t c = 0; c < actual.size(); ++c)
        if (isFloat ? float(declared[c]) != float(actual[c]) : declared[c] != actual[c]) declared[c] = actual[c];
    };
    exact(a.minValues, lo);
    exact(a.maxValues, hi);
  }
}

/// tinygltf writes a perspective camera's zfar even when it is 0, which tinygltf and
/// prt::Camera read as an infinite projection; glTF wants zfar positive, or absent for an
/// infinite projection. Leaves it out where it is not positive.
void leaveOutInfiniteZfar(Json& doc) {
  auto cameras = doc.find("cameras");
  if (cameras == doc.end() || !cameras->is_array()) return;
  for (Json& camera : *cameras) {
    auto perspective = camera.find("perspective");
    if (perspective == camera.end() || !perspective->is_object()) continue;
    auto zfar = perspective->find("zfar");
    if (zfar != perspective->end() && zfar->is_number() && !(zfar->get<double>() > 0.0)) perspective->erase(zfar);
  }
}

/// The model's glTF JSON as tinygltf serialises it. `binary`: without the bytes of buffer 0,
/// which the caller writes as the GLB's BIN chunk (moved out of the model meanwhile, so that
/// they are never copied); else with every buffer as a base64 data: URI.
Json serializedDocument(tinygltf::Model& m, bool binary) {
  std::vector<unsigned char> bin;
  if (binary) std::swap(bin, m.buffers[0].data);
  tinygltf::TinyGLTF writer;
  writer.SetImageWriter(&keepImageUri, nullptr);
  std::ostringstream json;
  const bool ok = writer.WriteGltfSceneToStream(&m, json, /*prettyPrint=*/false, /*writeBinary=*/false);
  if (binary) std::swap(bin, m.buffers[0].data);
  PRT_CHECK(ok);  // writing to memory fails only for a model prt made wrong
  Json doc = Json::parse(json.str());
  if (binary) {
    Json& buffer = doc.at("buffers").at(0);
    buffer.erase("uri");
    buffer["byteLength"] = m.buffers[0].data.size();
  }
  return doc;
}

void writeLittle32(std::ostream& out, uint32_t v) {
  const unsigned char bytes[4] = {uint8_t(v), uint8_t(v >> 8), uint8_t(v >> 16), uint8_t(v >> 24)};
  out.write(reinterpret_cast<const char*>(bytes), 4);
}

/// A GLB file (glTF 2.0, "GLB File Format Specification"): the 12-byte header, the JSON chunk
/// padded with spaces and the BIN chunk padded with zeros, each to 4 bytes.
void writeGlbChunks(std::ostream& out, std::string json, const std::vector<unsigned char>& bin) {
  json.resize((json.size() + 3) / 4 * 4, ' ');
  const size_t binPadded = (bin.size() + 3) / 4 * 4;
  const uint64_t length = 12 + 8 + json.size() + (bin.empty() ? 0 : 8 + binPadded);
  if (length > std::numeric_limits<uint32_t>::max())
    throw Error(cat("the .glb would be ", length, " bytes; the format holds at most 4 GiB"));
  out.write("glTF", 4);
  writeLittle32(out, 2);
  writeLittle32(out, uint32_t(length));
  writeLittle32(out, uint32_t(json.size()));
  out.write("JSON", 4);
  out.write(json.data(), std::streamsize(json.size()));
  if (bin.empty()) return;
  writeLittle32(out, uint32_t(binPadded));
  out.write("BIN\0", 4);
  out.write(reinterpret_cast<const char*>(bin.data()), std::streamsize(bin.size()));
  out.write("\0\0\0", std::streamsize(binPadded - bin.size()));
}

bool endsInGltf(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext == ".gltf";
}

}  // namespace

void writeSceneFile(const Gltf& g, tinygltf::Model& m, int& staging, const std::string& outPath) {
  m.asset.generator = "prt";
  embedImages(m, staging);
  packIntoOneBuffer(g, m);
  exactBounds(g, m);
  const bool binary = !endsInGltf(outPath);
  Json doc = serializedDocument(m, binary);
  leaveOutInfiniteZfar(doc);
  AtomicFile file(outPath);
  std::ofstream out(file.tempPath(), std::ios::binary | std::ios::trunc);
  if (binary)
    writeGlbChunks(out, doc.dump(), m.buffers[0].data);
  else
    out << doc.dump();
  out.close();
  if (!out) throw Error(cat(outPath, ": cannot write the ", binary ? ".glb" : ".gltf", " file"));
  file.commit();
}

}  // namespace prt::gltf
