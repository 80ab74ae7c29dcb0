// glTF 2.0 writing: writeBakedScene, and the edits it shares with writeLitScene
// (gltf_write_lit.cpp, through gltf_write.h) on the input model read again. The file itself,
// .glb or .gltf: gltf_glb.cpp.
#include "prt/scene.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <set>
#include <type_traits>

#include <nlohmann/json.hpp>

#include "bake_record_json.h"
#include "gltf_operator.h"
#include "gltf_write.h"
#include "prt/error.h"

namespace prt {

using namespace gltf;

namespace {

using Json = nlohmann::json;

tinygltf::Value toValue(const Json& j) {
  switch (j.type()) {
    case Json::value_t::boolean:
      return tinygltf::Value(j.get<bool>());
    case Json::value_t::number_integer:
    case Json::value_t::number_unsigned: {
      // tinygltf's Value holds 32-bit ints; larger integers survive as doubles.
      if (j.is_number_unsigned() ? j.get<uint64_t>() <= uint64_t(std::numeric_limits<int>::max())
                                 : (j.get<int64_t>() >= std::numeric_limits<int>::min() &&
                                    j.get<int64_t>() <= std::numeric_limits<int>::max()))
        return tinygltf::Value(static_cast<int>(j.get<int64_t>()));
      return tinygltf::Value(j.get<double>());
    }
    case Json::value_t::number_float:
      return tinygltf::Value(j.get<double>());
    case Json::value_t::string:
      return tinygltf::Value(j.get<std::string>());
    case Json::value_t::array: {
      tinygltf::Value::Array a;
      for (const Json& e : j) a.push_back(toValue(e));
      return tinygltf::Value(std::move(a));
    }
    case Json::value_t::object: {
      tinygltf::Value::Object o;
      for (const auto& [key, value] : j.items()) o[key] = toValue(value);
      return tinygltf::Value(std::move(o));
    }
    default:
      return tinygltf::Value();
  }
}

// ---------------------------------------------------------------------------------------------
// Writing: edits on the reloaded input model

/// A float accessor of `count` elements of `type` (TINYGLTF_TYPE_VEC3, _SCALAR) over `bytes`.
int addFloatAccessor(tinygltf::Model& m, int& staging, const void* bytes, size_t size, size_t count, int type,
                     const std::string& name) {
  tinygltf::Accessor a;
  a.name = name;
  a.bufferView = appendBufferView(m, stagingBuffer(m, staging), bytes, size, TINYGLTF_TARGET_ARRAY_BUFFER);
  a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  a.type = type;
  a.count = count;
  m.accessors.push_back(a);
  return static_cast<int>(m.accessors.size() - 1);
}

int addScalarAccessor(tinygltf::Model& m, int& staging, const std::vector<float>& values, const std::string& name) {
  return addFloatAccessor(m, staging, values.data(), values.size() * sizeof(float), values.size(), TINYGLTF_TYPE_SCALAR,
                          name);
}

/// Makes `prim` a triangle list with `indices` (UNSIGNED_INT, in the staging buffer).
void setTriangleList(tinygltf::Model& m, int& staging, tinygltf::Primitive& prim,
                     const std::vector<uint32_t>& indices) {
  tinygltf::Accessor a;
  a.bufferView = appendBufferView(m, stagingBuffer(m, staging), indices.data(), indices.size() * sizeof(uint32_t),
                                  TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
  a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  a.type = TINYGLTF_TYPE_SCALAR;
  a.count = indices.size();
  m.accessors.push_back(a);
  prim.indices = static_cast<int>(m.accessors.size() - 1);
  prim.mode = TINYGLTF_MODE_TRIANGLES;
}

/// The instances must still describe the file: same node → mesh, primitive and vertex count
/// (or, for a primitive split for flat normals, file vertices that exist).
void checkMatchesScene(const Gltf& g, const Scene& scene) {
  const tinygltf::Model& m = g.model;
  for (const MeshInstance& inst : scene.meshes) {
    bool ok = inst.node >= 0 && size_t(inst.node) < m.nodes.size() && m.nodes[size_t(inst.node)].mesh == inst.mesh &&
              inst.mesh >= 0 && size_t(inst.mesh) < m.meshes.size() && inst.primitive >= 0 &&
              size_t(inst.primitive) < m.meshes[size_t(inst.mesh)].primitives.size();
    if (ok) {
      const auto& attrs = m.meshes[size_t(inst.mesh)].primitives[size_t(inst.primitive)].attributes;
      auto pos = attrs.find("POSITION");
      ok = pos != attrs.end() && pos->second >= 0 && size_t(pos->second) < m.accessors.size();
      const size_t count = ok ? m.accessors[size_t(pos->second)].count : 0;
      if (ok && !inst.fileBlend.empty())
        ok = inst.fileBlend.size() == inst.vertexCount() &&
             std::all_of(inst.fileBlend.begin(), inst.fileBlend.end(), [&](const MeshInstance::FileBlend& b) {
               return b.vertex[0] < count && b.vertex[1] < count && b.vertex[2] < count;
             });
      else if (ok && inst.fileVertex.empty())
        ok = count == inst.vertexCount();
      else if (ok)
        ok = inst.fileVertex.size() == inst.vertexCount() &&
             std::all_of(inst.fileVertex.begin(), inst.fileVertex.end(), [&](uint32_t v) { return v < count; });
    }
    if (!ok)
      fail(g, cat("node ", inst.node, " / ", primitiveWhere(inst.mesh, inst.primitive),
                  " does not match the loaded scene (was the file changed?)"));
  }
}

/// The meshes the scene's instances come from: the writers touch only these, so meshes no node
/// of the default scene uses pass through as they are, whatever they hold.
std::set<int> usedMeshes(const Scene& scene) {
  std::set<int> used;
  for (const MeshInstance& inst : scene.meshes) used.insert(inst.mesh);
  return used;
}

/// Rewrites every strip and fan as a triangle list with its own index accessor.
void rewriteStripsAndFans(Gltf& g, int& staging, const std::set<int>& meshes) {
  tinygltf::Model& m = g.model;
  for (int mesh : meshes) {
    const size_t mi = size_t(mesh);
    for (size_t pi = 0; pi < m.meshes[mi].primitives.size(); ++pi) {
      tinygltf::Primitive& prim = m.meshes[mi].primitives[pi];
      if (prim.mode != TINYGLTF_MODE_TRIANGLE_STRIP && prim.mode != TINYGLTF_MODE_TRIANGLE_FAN) continue;
      std::string where = primitiveWhere(int(mi), int(pi));
      auto pos = prim.attributes.find("POSITION");
      if (pos == prim.attributes.end()) continue;
      size_t n = openAccessor(g, pos->second, cat(where, " / POSITION")).count;
      std::vector<uint32_t> list = toTriangleList(g, prim.mode, readIndices(g, prim, where, n), where);
      setTriangleList(m, staging, prim, list);
    }
  }
}

/// Per-vertex data belongs to a (node, primitive) pair, but glTF attaches attributes to
/// meshes: a mesh placed by several nodes gets one copy per extra node.
void giveEachNodeItsOwnMesh(tinygltf::Model& m, const Scene& scene) {
  std::map<int, int> owner;  // mesh -> the node that keeps it
  for (const MeshInstance& inst : scene.meshes) {
    auto [it, first] = owner.emplace(inst.mesh, inst.node);
    if (first || it->second == inst.node) continue;
    tinygltf::Node& node = m.nodes[size_t(inst.node)];
    if (node.mesh != inst.mesh) continue;  // already given its copy
    m.meshes.push_back(m.meshes[size_t(inst.mesh)]);
    node.mesh = static_cast<int>(m.meshes.size() - 1);
  }
}

/// A new accessor whose element i is element from[i] of accessor `index`, byte for byte (any
/// component type, normalized or not; min and max stay valid, every element being kept).
int gatheredAccessor(Gltf& g, int& staging, int index, const std::vector<uint32_t>& from, const std::string& where) {
  const AccessorData d = openAccessor(g, index, where);
  tinygltf::Accessor a = g.model.accessors[size_t(index)];
  for (uint32_t v : from)
    if (v >= d.count) fail(g, cat(where, ": vertex ", v, " does not exist (", d.count, " values)"));
  a.count = from.size();
  a.byteOffset = 0;
  if (d.bytes) {
    // glTF aligns each vertex attribute element to 4 bytes (a VEC3 of bytes takes 4).
    const size_t element = size_t(componentSize(d.componentType)) * size_t(d.components);
    const size_t stride = (element + 3) / 4 * 4;
    std::vector<unsigned char> bytes(from.size() * stride, 0);
    for (size_t i = 0; i < from.size(); ++i) std::memcpy(&bytes[i * stride], d.bytes + from[i] * d.stride, element);
    a.bufferView = appendBufferView(g.model, stagingBuffer(g.model, staging), bytes.data(), bytes.size(),
                                    TINYGLTF_TARGET_ARRAY_BUFFER);
    if (stride != element) g.model.bufferViews[size_t(a.bufferView)].byteStride = stride;
  }
  g.model.accessors.push_back(a);
  return static_cast<int>(g.model.accessors.size() - 1);
}

/// A primitive whose vertices the reader split for flat normals (MeshInstance::fileVertex) is
/// written with the split vertices: every attribute and morph target gathered, the instance's
/// triangles (in the file's winding) and the flat normals as NORMAL, so that reading the baked
/// file gives the vertices its transfer belongs to. Mesh copies of one primitive share the
/// rewrite.
void rewriteSplitPrimitives(Gltf& g, int& staging, const Scene& scene) {
  tinygltf::Model& m = g.model;
  std::map<std::pair<int, int>, tinygltf::Primitive> done;  // (mesh, primitive) of the file -> rewrite
  for (const MeshInstance& inst : scene.meshes) {
    if (inst.fileVertex.empty()) continue;
    tinygltf::Primitive& prim = primitiveOf(m, inst);
    const auto key = std::make_pair(inst.mesh, inst.primitive);
    if (auto it = done.find(key); it != done.end()) {
      prim = it->second;
      continue;
    }
    const std::string where = primitiveWhere(inst.mesh, inst.primitive);
    for (auto& [name, a] : prim.attributes)
      a = gatheredAccessor(g, staging, a, inst.fileVertex, cat(where, " / ", name));
    for (size_t t = 0; t < prim.targets.size(); ++t)
      for (auto& [name, a] : prim.targets[t])
        a = gatheredAccessor(g, staging, a, inst.fileVertex, cat(where, " / target ", t, " / ", name));
    std::vector<uint32_t> indices = inst.indices;
    if (glm::determinant(glm::dmat3(inst.world)) < 0.0)  // the reader swapped two corners
      for (size_t t = 0; t + 2 < indices.size(); t += 3) std::swap(indices[t + 1], indices[t + 2]);
    const AccessorData pos = openAccessor(g, prim.attributes.at("POSITION"), cat(where, " / POSITION"));
    std::vector<glm::vec3> positions(pos.count);
    for (size_t v = 0; v < pos.count; ++v)
      for (int c = 0; c < 3; ++c) positions[v][c] = static_cast<float>(pos.get(v, c));
    prim.attributes["NORMAL"] = addVec3Accessor(m, staging, flatVertexNormals(positions, indices), "flat normals");
    setTriangleList(m, staging, prim, indices);
    prim.extensions.erase("KHR_draco_mesh_compression");  // the new accessors are plain
    done.emplace(key, prim);
  }
}

/// The file vertex of a blend with the largest weight (the first of equal ones).
uint32_t dominantVertex(const MeshInstance::FileBlend& b) {
  int best = 0;
  for (int j = 1; j < 3; ++j)
    if (b.weight[j] > b.weight[best]) best = j;
  return b.vertex[best];
}

/// How a refined vertex gets an attribute: interpolated (float, normalised and float data),
/// interpolated then renormalised (NORMAL; TANGENT's xyz, its handedness w from the dominant
/// vertex), or copied from the dominant file vertex (integer data such as JOINTS_n, and
/// WEIGHTS_n, which belong to those joints).
enum class BlendKind { Linear, Unit, Tangent, Nearest };

BlendKind blendKind(const std::string& name, const AccessorData& d) {
  if (name.rfind("JOINTS_", 0) == 0 || name.rfind("WEIGHTS_", 0) == 0) return BlendKind::Nearest;
  if (d.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !d.normalized) return BlendKind::Nearest;
  if (name == "NORMAL" && d.components == 3) return BlendKind::Unit;
  if (name == "TANGENT" && d.components == 4) return BlendKind::Tangent;
  return BlendKind::Linear;
}

/// A new float accessor whose element i is blends[i] of accessor `index`'s elements. Each sum
/// runs over its terms sorted by weight and value, so vertices made from equal values (the
/// two sides of a UV seam) get equal bits and the refined surface stays closed. POSITION gets
/// the min/max glTF requires.
int blendedAccessor(Gltf& g, int& staging, int index, const std::string& name,
                    const std::vector<MeshInstance::FileBlend>& blends, const std::string& where) {
  const AccessorData d = openAccessor(g, index, where);
  const BlendKind kind = blendKind(name, d);
  if (kind == BlendKind::Nearest) {
    std::vector<uint32_t> from(blends.size());
    for (size_t i = 0; i < blends.size(); ++i) from[i] = dominantVertex(blends[i]);
    return gatheredAccessor(g, staging, index, from, where);
  }
  const int n = d.components;
  std::vector<float> out(blends.size() * size_t(n));
  for (size_t i = 0; i < blends.size(); ++i) {
    const MeshInstance::FileBlend& b = blends[i];
    std::array<std::pair<double, std::array<double, 4>>, 3> terms{};
    for (int j = 0; j < 3; ++j) {
      terms[size_t(j)].first = b.weight[j];
      for (int c = 0; c < n; ++c)
        terms[size_t(j)].second[size_t(c)] = b.weight[j] != 0.0f ? d.get(b.vertex[j], c) : 0.0;
    }
    std::sort(terms.begin(), terms.end());
    std::array<double, 4> v{};
    for (const auto& [w, value] : terms)
      for (int c = 0; c < n; ++c) v[size_t(c)] += w * value[size_t(c)];
    if (kind == BlendKind::Unit || kind == BlendKind::Tangent) {
      const double len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
      if (len > 0.0)
        for (int c = 0; c < 3; ++c) v[size_t(c)] /= len;
      if (kind == BlendKind::Tangent) v[3] = d.get(dominantVertex(b), 3) < 0.0 ? -1.0 : 1.0;
    }
    for (int c = 0; c < n; ++c) out[i * size_t(n) + size_t(c)] = static_cast<float>(v[size_t(c)]);
  }
  tinygltf::Accessor a;
  a.name = g.model.accessors[size_t(index)].name;
  a.type = g.model.accessors[size_t(index)].type;
  a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  a.count = blends.size();
  a.bufferView = appendBufferView(g.model, stagingBuffer(g.model, staging), out.data(), out.size() * sizeof(float),
                                  TINYGLTF_TARGET_ARRAY_BUFFER);
  if (name == "POSITION" && n == 3 && !blends.empty()) {
    a.minValues.assign(3, std::numeric_limits<double>::infinity());
    a.maxValues.assign(3, -std::numeric_limits<double>::infinity());
    for (size_t i = 0; i < blends.size(); ++i)
      for (int c = 0; c < 3; ++c) {
        a.minValues[size_t(c)] = std::min(a.minValues[size_t(c)], double(out[i * 3 + size_t(c)]));
        a.maxValues[size_t(c)] = std::max(a.maxValues[size_t(c)], double(out[i * 3 + size_t(c)]));
      }
  }
  g.model.accessors.push_back(a);
  return static_cast<int>(g.model.accessors.size() - 1);
}

/// A primitive the bake refined (MeshInstance::fileBlend) is written with its refined
/// vertices: every attribute and morph target interpolated (blendedAccessor), the refined
/// triangles (in the file's winding), and, where the file has no NORMAL, the flat normals of
/// the refined triangles, so that reading the baked file gives the vertices its transfer
/// belongs to. Each instance has its own mesh by now (giveEachNodeItsOwnMesh).
void rewriteRefinedPrimitives(Gltf& g, int& staging, const Scene& scene) {
  tinygltf::Model& m = g.model;
  for (const MeshInstance& inst : scene.meshes) {
    if (inst.fileBlend.empty()) continue;
    tinygltf::Primitive& prim = primitiveOf(m, inst);
    const std::string where = primitiveWhere(inst.mesh, inst.primitive);
    for (auto& [name, a] : prim.attributes)
      a = blendedAccessor(g, staging, a, name, inst.fileBlend, cat(where, " / ", name));
    for (size_t t = 0; t < prim.targets.size(); ++t)
      for (auto& [name, a] : prim.targets[t])
        a = blendedAccessor(g, staging, a, name, inst.fileBlend, cat(where, " / target ", t, " / ", name));
    std::vector<uint32_t> indices = inst.indices;
    if (glm::determinant(glm::dmat3(inst.world)) < 0.0)  // the reader swapped two corners
      for (size_t t = 0; t + 2 < indices.size(); t += 3) std::swap(indices[t + 1], indices[t + 2]);
    if (!prim.attributes.count("NORMAL")) {
      const AccessorData pos = openAccessor(g, prim.attributes.at("POSITION"), cat(where, " / POSITION"));
      std::vector<glm::vec3> positions(pos.count);
      for (size_t v = 0; v < pos.count; ++v)
        for (int c = 0; c < 3; ++c) positions[v][c] = static_cast<float>(pos.get(v, c));
      prim.attributes["NORMAL"] = addVec3Accessor(m, staging, flatVertexNormals(positions, indices), "flat normals");
    }
    setTriangleList(m, staging, prim, indices);
    prim.extensions.erase("KHR_draco_mesh_compression");  // the new accessors are plain
  }
}

void dropTransferAttributes(tinygltf::Model& m) {
  for (tinygltf::Mesh& mesh : m.meshes)
    for (tinygltf::Primitive& prim : mesh.primitives)
      std::erase_if(prim.attributes, [](const auto& a) { return a.first.rfind(kTransferPrefix, 0) == 0; });
}

void addTransferAttributes(tinygltf::Model& m, int& staging, const Scene& scene) {
  size_t k = size_t(scene.transferBands) * size_t(scene.transferBands);
  for (const MeshInstance& inst : scene.meshes) {
    if (inst.transfer.empty()) continue;
    PRT_CHECK_GT(scene.transferBands, 0);
    PRT_CHECK_EQ(inst.transfer.size(), inst.vertexCount() * k);
    tinygltf::Primitive& prim = primitiveOf(m, inst);
    // One attribute per coefficient: RGB sets as VEC3, the colourless direct parts as SCALAR.
    auto addSet = [&](const auto& values, bool back, bool direct) {
      if (values.empty()) return;  // one-sided (no back side), or no direct part kept
      PRT_CHECK_EQ(values.size(), inst.vertexCount() * k);
      std::vector<std::decay_t<decltype(values[0])>> column(inst.vertexCount());
      for (size_t i = 0; i < k; ++i) {
        for (size_t v = 0; v < column.size(); ++v) column[v] = values[v * k + i];
        const std::string name = coefficientName(int(i), back, direct);
        if constexpr (std::is_same_v<decltype(column), std::vector<float>>)
          prim.attributes[name] = addScalarAccessor(m, staging, column, name);
        else
          prim.attributes[name] = addVec3Accessor(m, staging, column, name);
      }
    };
    PRT_CHECK(inst.transferDirectBack.empty() || !inst.transferBack.empty());
    addSet(inst.transfer, false, false);
    addSet(inst.transferBack, true, false);
    addSet(inst.transferDirect, false, true);
    addSet(inst.transferDirectBack, true, true);
  }
}

/// Receivers named only by LoadOptions::receiverNodes (prt bake --receiver) get extras
/// {"prt": {"receiver": true}} on their node in the written file, so that loading it again
/// (prt render, prt info) finds the same receivers. Other extras are kept.
void markOptionReceivers(tinygltf::Model& m, const Scene& scene) {
  using Object = tinygltf::Value::Object;
  for (const MeshInstance& inst : scene.meshes) {
    if (inst.receiverReason != ReceiverReason::Option) continue;
    tinygltf::Value& extras = m.nodes[size_t(inst.node)].extras;
    Object root = extras.IsObject() ? extras.Get<Object>() : Object{};
    Object prt = root.count("prt") && root["prt"].IsObject() ? root["prt"].Get<Object>() : Object{};
    prt["receiver"] = tinygltf::Value(true);
    root["prt"] = tinygltf::Value(std::move(prt));
    extras = tinygltf::Value(std::move(root));
  }
}

/// Stores the record as asset.extras.prt. It is read back through the reader's checks first,
/// so that prt never writes a record it would refuse to load.
void storeRecord(const Scene& scene, tinygltf::Model& m, const BakeRecord* record, const std::string& outPath) {
  if (!record) return;
  const std::string where = cat(outPath, ": asset.extras.prt");
  const Json json = bakeRecordToJson(*record);
  bakeRecordFromJson(json, where);
  const bool anyTransfer =
      std::any_of(scene.meshes.begin(), scene.meshes.end(), [](const MeshInstance& i) { return !i.transfer.empty(); });
  if (anyTransfer && record->bands != scene.transferBands)
    throw Error(cat(where, ".bands: ", record->bands, ", but the transfer holds ", scene.transferBands, " bands"));
  const bool anyBack =
      std::any_of(scene.meshes.begin(), scene.meshes.end(), [](const MeshInstance& i) { return i.hasBackTransfer(); });
  if (anyBack != record->backTransfer)
    throw Error(cat(where, ".back_transfer: the record ", record->backTransfer ? "says" : "does not say",
                    " that double-sided primitives carry back-side transfer, but ", anyBack ? "some do" : "none does"));
  const bool allDirect =
      anyTransfer && std::all_of(scene.meshes.begin(), scene.meshes.end(), [](const MeshInstance& i) {
        return i.transfer.empty() || (i.hasDirectTransfer() && i.hasBackTransfer() == !i.transferDirectBack.empty());
      });
  const bool anyDirect = std::any_of(scene.meshes.begin(), scene.meshes.end(),
                                     [](const MeshInstance& i) { return i.hasDirectTransfer(); });
  if (anyDirect != record->directTransfer || (anyDirect && !allDirect))
    throw Error(cat(where, ".direct_transfer: the record ", record->directTransfer ? "says" : "does not say",
                    " that every baked primitive carries its direct part, but ",
                    anyDirect ? (allDirect ? "all do" : "only some do") : "none does"));
  if (!m.asset.extras.IsObject()) m.asset.extras = tinygltf::Value(tinygltf::Value::Object{});
  m.asset.extras.Get<tinygltf::Value::Object>()["prt"] = toValue(json);
}

/// glTF requires min/max on POSITION accessors; inputs that lack them get them here, so the
/// output validates whatever the input did.
void addPositionBounds(Gltf& g, const std::set<int>& meshes) {
  for (int mesh : meshes) {
    const size_t mi = size_t(mesh);
    for (size_t pi = 0; pi < g.model.meshes[mi].primitives.size(); ++pi) {
      const auto& attrs = g.model.meshes[mi].primitives[pi].attributes;
      auto pos = attrs.find("POSITION");
      if (pos == attrs.end()) continue;
      std::string where = cat(primitiveWhere(int(mi), int(pi)), " / POSITION");
      AccessorData d = openAccessor(g, pos->second, where);
      tinygltf::Accessor& a = g.model.accessors[size_t(pos->second)];
      if (d.count == 0 || d.components != 3 || (a.minValues.size() == 3 && a.maxValues.size() == 3)) continue;
      glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
      for (size_t v = 0; v < d.count; ++v) {
        glm::dvec3 p(d.get(v, 0), d.get(v, 1), d.get(v, 2));
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
      }
      a.minValues = {lo.x, lo.y, lo.z};
      a.maxValues = {hi.x, hi.y, hi.z};
    }
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The steps gltf_write.h shares with gltf_write_lit.cpp

int gltf::addVec3Accessor(tinygltf::Model& m, int& staging, const std::vector<glm::vec3>& values,
                          const std::string& name) {
  return addFloatAccessor(m, staging, values.data(), values.size() * sizeof(glm::vec3), values.size(),
                          TINYGLTF_TYPE_VEC3, name);
}

tinygltf::Primitive& gltf::primitiveOf(tinygltf::Model& m, const MeshInstance& inst) {
  return m.meshes[size_t(m.nodes[size_t(inst.node)].mesh)].primitives[size_t(inst.primitive)];
}

void gltf::addExtensionUsed(tinygltf::Model& m, const std::string& name) {
  if (std::find(m.extensionsUsed.begin(), m.extensionsUsed.end(), name) == m.extensionsUsed.end())
    m.extensionsUsed.push_back(name);
}

Gltf gltf::reloadForWriting(const std::string& inputPath, const Scene& scene, int& staging) {
  Gltf g = readGltf(inputPath, nullptr, scene.allowExternalUris);
  checkMatchesScene(g, scene);
  const std::set<int> meshes = usedMeshes(scene);
  addPositionBounds(g, meshes);
  rewriteStripsAndFans(g, staging, meshes);
  giveEachNodeItsOwnMesh(g.model, scene);
  dropTransferAttributes(g.model);
  dropOperator(g.model);
  rewriteSplitPrimitives(g, staging, scene);
  rewriteRefinedPrimitives(g, staging, scene);
  return g;
}

void writeBakedScene(const std::string& inputPath, const Scene& scene, const BakeRecord* record,
                     const std::string& outPath) {
  int staging = -1;
  Gltf g = reloadForWriting(inputPath, scene, staging);
  addTransferAttributes(g.model, staging, scene);
  markOptionReceivers(g.model, scene);
  storeRecord(scene, g.model, record, outPath);
  if (scene.bounceOperator) storeOperator(g.model, staging, *scene.bounceOperator);
  writeSceneFile(g, g.model, staging, outPath);
}

}  // namespace prt
