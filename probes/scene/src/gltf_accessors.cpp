// glTF accessors: every accessor checked against its buffer view and buffer before a byte is
// read (tinygltf is never trusted with bounds), index lists and triangle lists from them.
// Part of the glTF reader (gltf_reader.h); componentSize and AccessorData are in gltf_model.h.
#include <algorithm>
#include <string>
#include <vector>

#include "gltf_reader.h"
#include "prt/error.h"

namespace prt::gltf {

namespace {

// An accessor without a buffer view reads as zeros: its count is not backed by bytes of the
// file, so it is bounded here instead of by the buffer (a limit on hostile input,
// docs/robustness.md).
constexpr size_t kMaxBufferlessCount = size_t(1) << 24;

int componentCount(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return 1;
    case TINYGLTF_TYPE_VEC2:
      return 2;
    case TINYGLTF_TYPE_VEC3:
      return 3;
    case TINYGLTF_TYPE_VEC4:
      return 4;
    default:
      return 0;  // matrices are never vertex data we read
  }
}

}  // namespace

const char* typeName(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return "SCALAR";
    case TINYGLTF_TYPE_VEC2:
      return "VEC2";
    case TINYGLTF_TYPE_VEC3:
      return "VEC3";
    case TINYGLTF_TYPE_VEC4:
      return "VEC4";
    default:
      return "a matrix type";
  }
}

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
  if (d.components == 0)
    fail(g, cat(where, ": accessor ", index, " has type ", typeName(a.type), ", expected a scalar or vector"));
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
                view.byteOffset + view.byteLength, ") runs past the end of buffer ", view.buffer, " (",
                buffer.data.size(), " bytes)"));
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
      fail(g, cat(where, ": accessor ", index, " (", d.count, " elements, stride ", d.stride, ", offset ", a.byteOffset,
                  ") runs past the end of buffer view ", a.bufferView, " (", view.byteLength, " bytes)"));
  }
  d.bytes = buffer.data.data() + view.byteOffset + a.byteOffset;
  return d;
}

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
  if (d.count != expected) fail(g, cat(where, ": ", d.count, " values, expected ", expected, " (the POSITION count)"));
}

/// Index values of a primitive (or 0..n-1 without indices), each checked against the vertex count.
std::vector<uint32_t> readIndices(const Gltf& g, const tinygltf::Primitive& prim, const std::string& where,
                                  size_t vertexCount) {
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
      fail(g, cat(here, ": index ", i, " is ", uint64_t(v), ", out of range (the primitive has ", vertexCount,
                  " vertices)"));
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

}  // namespace prt::gltf
