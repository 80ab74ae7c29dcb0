// The .glb container (gltf_glb.h): images embedded with their original encoded bytes, every
// buffer view still referred to packed into one buffer, and the file written atomically.
#include "gltf_glb.h"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "prt/atomic_file.h"
#include "prt/error.h"

namespace prt::gltf {

namespace fs = std::filesystem;

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
bool keepImageUri(const std::string*, const std::string*, const tinygltf::Image*, bool,
                  std::string*, void*) {
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
  auto mark = [&](int a) { if (a >= 0 && size_t(a) < used.size()) used[size_t(a)] = 1; };
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
    for (const tinygltf::AnimationSampler& s : anim.samplers) { mark(s.input); mark(s.output); }
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
  auto map = [&](int& a) { if (a >= 0 && size_t(a) < to.size()) a = to[size_t(a)]; };
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
    for (tinygltf::AnimationSampler& s : anim.samplers) { map(s.input); map(s.output); }
}

/// GLB holds one binary buffer: copies every kept buffer view into a new buffer 0, dropping
/// views (and, with only known extensions, accessors) that nothing refers to any more —
/// a lit scene then no longer carries the transfer it was made from.
void packIntoOneBuffer(const Gltf& g, tinygltf::Model& m) {
  bool prune = onlyKnownExtensions(m);
  if (prune) remapAccessors(m, usedAccessors(m));
  std::vector<char> keepView(m.bufferViews.size(), prune ? 0 : 1);
  auto mark = [&](int v) { if (v >= 0 && size_t(v) < keepView.size()) keepView[size_t(v)] = 1; };
  for (const tinygltf::Accessor& a : m.accessors) {
    mark(a.bufferView);
    if (a.sparse.isSparse) { mark(a.sparse.indices.bufferView); mark(a.sparse.values.bufferView); }
  }
  for (const tinygltf::Image& image : m.images) mark(image.bufferView);

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
  auto map = [&](int& v) { if (v >= 0 && size_t(v) < to.size()) v = to[size_t(v)]; };
  for (tinygltf::Accessor& a : m.accessors) {
    map(a.bufferView);
    if (a.sparse.isSparse) { map(a.sparse.indices.bufferView); map(a.sparse.values.bufferView); }
  }
  for (tinygltf::Image& image : m.images) map(image.bufferView);
  m.bufferViews = std::move(views);
  m.buffers.assign(1, std::move(packed));
}

}  // namespace

void writeGlb(const Gltf& g, tinygltf::Model& m, int& staging, const std::string& outPath) {
  m.asset.generator = "prt";
  embedImages(m, staging);
  packIntoOneBuffer(g, m);
  AtomicFile file(outPath);
  tinygltf::TinyGLTF writer;
  writer.SetImageWriter(&keepImageUri, nullptr);
  bool ok = writer.WriteGltfSceneToFile(&m, file.tempPath(), /*embedImages=*/true, /*embedBuffers=*/true,
                                        /*prettyPrint=*/false, /*writeBinary=*/true);
  // tinygltf does not check its stream writes; a truncated file shows in its size.
  std::error_code ec;
  uintmax_t size = fs::file_size(file.tempPath(), ec);
  if (!ok || ec || size < 12) throw Error(cat(outPath, ": cannot write the .glb file"));
  file.commit();
}

}  // namespace prt::gltf
