// The parsed glTF document and the pieces of the reader that the writers use too. The only
// header that includes tinygltf: the reader's files (gltf_read.cpp and the parts gltf_reader.h
// lists) and the writers' (gltf_write.cpp, gltf_write_lit.cpp, gltf_glb.cpp), which include
// it, are the only files of prt that see tinygltf.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <tiny_gltf.h>
#include <glm/glm.hpp>

#include "prt/error.h"

namespace prt::gltf {

constexpr const char* kTransferPrefix = "_PRT_SH_";
/// The back side's transfer of a double-sided primitive: _PRT_SH_BACK_00 .. (docs/formats.md).
constexpr const char* kBackTransferPrefix = "_PRT_SH_BACK_";
/// The direct part (bounce 0, colourless) of each set: _PRT_SH_DIRECT_00 .., _PRT_SH_BACK_DIRECT_00 ..
constexpr const char* kDirectTransferPrefix = "_PRT_SH_DIRECT_";
constexpr const char* kBackDirectTransferPrefix = "_PRT_SH_BACK_DIRECT_";
/// The back side's radiance of a double-sided primitive in a lit scene (_RADIANCE is the front's).
constexpr const char* kBackRadiance = "_PRT_COLOR_BACK";
constexpr const char* kUnlit = "KHR_materials_unlit";
constexpr const char* kLights = "KHR_lights_punctual";
constexpr const char* kTextureTransform = "KHR_texture_transform";
constexpr const char* kSpecularGlossiness = "KHR_materials_pbrSpecularGlossiness";
constexpr const char* kTransmission = "KHR_materials_transmission";
constexpr const char* kIor = "KHR_materials_ior";
constexpr const char* kSpecular = "KHR_materials_specular";
constexpr const char* kEmissiveStrength = "KHR_materials_emissive_strength";

/// A loaded glTF document and the path its messages start with.
struct Gltf {
  std::string path;
  tinygltf::Model model;
};

[[noreturn]] inline void fail(const Gltf& g, const std::string& what) { throw Error(cat(g.path, ": ", what)); }

inline std::string primitiveWhere(int mesh, int primitive) { return cat("mesh ", mesh, " / primitive ", primitive); }

/// The attribute name of transfer coefficient i: _PRT_SH_00, _PRT_SH_01, ... (`back`:
/// _PRT_SH_BACK_NN; `direct`: _PRT_SH_DIRECT_NN or _PRT_SH_BACK_DIRECT_NN).
inline const char* transferPrefix(bool back, bool direct) {
  return direct ? (back ? kBackDirectTransferPrefix : kDirectTransferPrefix)
                : (back ? kBackTransferPrefix : kTransferPrefix);
}
inline std::string coefficientName(int i, bool back = false, bool direct = false) {
  return cat(transferPrefix(back, direct), i < 10 ? "0" : "", i);
}

/// Reads and parses a .gltf or .glb file: the file itself, then every URI it holds through the
/// guard of uri_guard.h. tinygltf's warnings go to `warnings` (may be null).
Gltf readGltf(const std::string& path, std::vector<std::string>* warnings, bool allowExternal);

inline int componentSize(int componentType) {
  switch (componentType) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return 4;
    default:
      return 0;  // INT and DOUBLE are not glTF 2.0 accessor types
  }
}

/// A validated view of an accessor's elements; every read is within the buffer.
struct AccessorData {
  const unsigned char* bytes = nullptr;  // null: no buffer view, all values zero
  size_t count = 0;
  size_t stride = 0;
  int componentType = 0;
  int components = 0;
  bool normalized = false;

  /// Component c of element i, with normalized integers mapped as the glTF spec says.
  double get(size_t i, int c) const {
    if (!bytes) return 0.0;
    const unsigned char* p = bytes + i * stride + static_cast<size_t>(c) * componentSize(componentType);
    switch (componentType) {
      case TINYGLTF_COMPONENT_TYPE_FLOAT: {
        float v;
        std::memcpy(&v, p, 4);
        return v;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
        return normalized ? p[0] / 255.0 : p[0];
      case TINYGLTF_COMPONENT_TYPE_BYTE: {
        int8_t v;
        std::memcpy(&v, p, 1);
        return normalized ? std::max(v / 127.0, -1.0) : v;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        uint16_t v;
        std::memcpy(&v, p, 2);
        return normalized ? v / 65535.0 : v;
      }
      case TINYGLTF_COMPONENT_TYPE_SHORT: {
        int16_t v;
        std::memcpy(&v, p, 2);
        return normalized ? std::max(v / 32767.0, -1.0) : v;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
        uint32_t v;
        std::memcpy(&v, p, 4);
        return normalized ? v / 4294967295.0 : v;
      }
      default:
        return 0.0;
    }
  }
};

/// Checks accessor `index` (range, types, byte ranges of accessor, buffer view and buffer) and
/// returns a view on it. `where` names the user of the accessor, e.g. "mesh 0 / primitive 1 /
/// NORMAL".
AccessorData openAccessor(const Gltf& g, int index, const std::string& where);

/// Index values of a primitive (or 0..n-1 without indices), each checked against the vertex count.
std::vector<uint32_t> readIndices(const Gltf& g, const tinygltf::Primitive& prim, const std::string& where,
                                  size_t vertexCount);

/// Triangle list from TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN indices, in glTF's winding
/// (strips alternate: triangle i is p_i, p_{i+1+i%2}, p_{i+2-i%2}; fans are p_{i+1}, p_{i+2}, p_0).
std::vector<uint32_t> toTriangleList(const Gltf& g, int mode, const std::vector<uint32_t>& in,
                                     const std::string& where);

/// The normals of a primitive without NORMAL once its vertices are split for flat normals
/// (gltf_primitives.cpp): per vertex, the normalised area-weighted sum of its triangles' normals,
/// which are one orientation after the split; (0, 1, 0) where no triangle uses the vertex.
/// The reader and the writer both compute them with this, so a baked file holds the normals
/// the bake used.
std::vector<glm::vec3> flatVertexNormals(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& indices);

}  // namespace prt::gltf
