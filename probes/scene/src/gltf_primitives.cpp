// glTF primitives, read once per mesh/primitive in the primitive's own space: positions,
// normals, texture coordinates, colours and transfer sets, checked; degenerate triangles
// dropped; vertices split for flat normals where the file has none; and, once placed by a
// node, normals repaired where the file's are zero. Part of the glTF reader (gltf_reader.h).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include "gltf_reader.h"
#include "prt/error.h"
#include "prt/tangents.h"

namespace prt::gltf {

namespace {

/// Faces whose unit normals have a dot product at least this share a vertex under flat
/// normals: within 0.1°, which float positions of one plane never exceed, while real edges of
/// a mesh that needs flat shading are far sharper.
constexpr double kSameOrientation = 0.99999848;  // cos(0.1°)

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
  for (uint32_t v : from)
    out.insert(out.end(), values.begin() + std::ptrdiff_t(v * perVertex),
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
    for (std::vector<glm::vec2>& set : p.moreTexcoords) gather(set, fileVertex);
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
        fail(g,
             cat(where, ": transfer attribute ", coefficientName(i, back, direct), " is missing (", count, " found)"));
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

/// TEXCOORD_`set` of the primitive with `transform` applied, or empty where the primitive has
/// none (with a warning naming `user`, where not null).
std::vector<glm::vec2> readTexcoords(const Gltf& g, const tinygltf::Primitive& prim, const std::string& where, size_t n,
                                     int set, const glm::dmat3& transform, const char* user,
                                     std::vector<std::string>& warnings) {
  const std::string uvName = cat("TEXCOORD_", set);
  auto it = prim.attributes.find(uvName);
  if (it == prim.attributes.end()) {
    if (user) warnings.push_back(cat(g.path, ": ", where, ": no ", uvName, " for ", user, "; texture ignored"));
    return {};
  }
  std::string here = cat(where, " / ", uvName);
  AccessorData d = openAccessor(g, it->second, here);
  requireType(g, d, here, {2});
  requireCount(g, d, here, n);
  std::vector<glm::vec2> uv = readVectors<2>(d);
  if (transform != glm::dmat3(1.0))
    for (glm::vec2& c : uv) c = glm::vec2(transform * glm::dvec3(c, 1.0));
  return uv;
}

/// The normal map's tangents where the file gives none: MikkTSpace over the normal texture's
/// coordinates (prt/tangents.h), with a warning naming the material where some vertices got
/// the fallback frame. Nothing where the primitive lacks those coordinates (a warning said so).
void addTangents(const Gltf& g, const BaseColorSource& source, const std::string& where, PrimitiveData& p,
                 std::vector<std::string>& warnings) {
  const std::vector<glm::vec2>& uv =
      source.normalUvSet == 0 ? p.texcoords : p.moreTexcoords[size_t(source.normalUvSet) - 1];
  if (!p.tangents.empty() || uv.empty()) return;
  TangentResult t = generateTangents(p.positions, p.normals, uv, p.indices);
  p.tangents = std::move(t.tangents);
  if (t.degenerateVertices)
    warnings.push_back(cat(g.path, ": ", materialWhere(g, size_t(p.material)), ": ", where, ": ", t.degenerateVertices,
                           " of ", p.positions.size(),
                           " vertices have degenerate texture coordinates for the normal texture; their tangent "
                           "is an arbitrary direction orthogonal to the normal"));
}

}  // namespace

PrimitiveData readPrimitive(const Gltf& g, const std::vector<BaseColorSource>& materials, int meshIndex, int primIndex,
                            std::vector<std::string>& warnings) {
  const tinygltf::Primitive& prim = g.model.meshes[size_t(meshIndex)].primitives[size_t(primIndex)];
  std::string where = primitiveWhere(meshIndex, primIndex);
  PrimitiveData p;
  if (prim.mode >= TINYGLTF_MODE_POINTS && prim.mode <= TINYGLTF_MODE_LINE_STRIP) {
    warnings.push_back(
        cat(g.path, ": ", where, ": skipping mode ", modeName(prim.mode), " (only triangles are baked)"));
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
  const std::string user =
      source ? cat("the textures of ", materialWhere(g, size_t(p.material)), " that read it") : std::string();
  const char* baseUser = source && source->texture >= 0     ? "the base colour texture"
                         : source && source->extrasReadSet0 ? user.c_str()
                                                            : nullptr;
  p.texcoords = readTexcoords(g, prim, where, n, source ? source->texCoord : 0,
                              source ? source->uvTransform : glm::dmat3(1.0), baseUser, warnings);
  if (source) {
    for (const BaseColorSource::UvSet& set : source->moreUvSets)
      p.moreTexcoords.push_back(
          readTexcoords(g, prim, where, n, set.texCoord, set.uvTransform, user.c_str(), warnings));
  }
  if (auto it = prim.attributes.find("TANGENT"); it != prim.attributes.end() && source && source->normalUvSet >= 0) {
    std::string here = cat(where, " / TANGENT");
    AccessorData d = openAccessor(g, it->second, here);
    requireType(g, d, here, {4});
    requireCount(g, d, here, n);
    p.tangents = readVectors<4>(d);
    requireFinite(g, p.tangents, here);
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
  if (p.normals.empty()) {
    p.tangents.clear();  // glTF: without NORMAL, flat normals, and TANGENT is ignored
    splitForFlatNormals(p);
  }
  if (source && source->normalUvSet >= 0) addTangents(g, *source, where, p, warnings);
  return p;
}

/// Per vertex, the area-weighted sum of the normals of the triangles that use it, normalised;
/// (0, 1, 0) for a vertex no triangle uses.
std::vector<glm::vec3> flatVertexNormals(const std::vector<glm::vec3>& positions,
                                         const std::vector<uint32_t>& indices) {
  std::vector<glm::dvec3> sum(positions.size(), glm::dvec3(0.0));
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    const glm::dvec3 p0(positions[indices[t]]);
    const glm::dvec3 n =
        glm::cross(glm::dvec3(positions[indices[t + 1]]) - p0, glm::dvec3(positions[indices[t + 2]]) - p0);
    for (size_t k = 0; k < 3; ++k) sum[indices[t + k]] += n;
  }
  std::vector<glm::vec3> out(positions.size(), glm::vec3(0, 1, 0));
  for (size_t v = 0; v < sum.size(); ++v) {
    const double len = glm::length(sum[v]);
    if (len > 0.0 && std::isfinite(len)) out[v] = glm::vec3(sum[v] / len);
  }
  return out;
}

namespace {

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

}  // namespace

size_t setNormals(MeshInstance& inst, const PrimitiveData& p, const glm::dmat3& linear) {
  // cofactor(M) = det(M)·M^-T; scaled by sign(det) it is a positive multiple of M^-T and
  // stays defined for singular M.
  glm::dmat3 cof(glm::cross(linear[1], linear[2]), glm::cross(linear[2], linear[0]), glm::cross(linear[0], linear[1]));
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

}  // namespace prt::gltf
