// The global numbering of a surface bake's vertices and triangles (both sides) and what a hit
// keeps for the bounces: the order of the bake's transfer, hit records and checkpoints.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "prt/scene.h"

namespace prt::bake {

/// True when the instance's back side is baked too: a baked (non-receiver) instance of a
/// double-sided material. Its transfer then has 2 × vertexCount entries per coefficient set.
bool bakesBackSide(const Scene& scene, const MeshInstance& m);

// Global numbering of the baked (non-receiver) instances' vertices and triangles: first every
// instance's real vertices (front sides) and triangles, in scene order, then the virtual
// vertices and triangles (back sides) of the double-sided ones, in scene order.
struct Layout {
  static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
  std::vector<size_t> vertexOffset;      // per Scene::meshes entry (SIZE_MAX for receivers)
  std::vector<size_t> backVertexOffset;  // per mesh, its first virtual vertex (SIZE_MAX: one-sided)
  std::vector<uint32_t> triOffset;       // per mesh, global index of its first triangle
  std::vector<uint32_t> backTriOffset;   // per mesh, its first virtual triangle (kNone: one-sided)
  std::vector<uint32_t> meshOfVertex;
  std::vector<uint32_t> triVerts;  // global triangle -> 3 global vertex indices
  std::vector<uint32_t> meshOfTri;
  size_t frontVertices = 0;   // real vertices; virtual ones are [frontVertices, vertices)
  size_t frontTriangles = 0;  // real triangles; virtual ones are [frontTriangles, triangles)
  size_t vertices = 0;
  size_t triangles = 0;

  bool isBack(size_t v) const { return v >= frontVertices; }
  /// The instance's own index of global vertex v (a virtual vertex: the vertex it is the back of).
  size_t localVertex(size_t v) const {
    const uint32_t k = meshOfVertex[v];
    return v - (isBack(v) ? backVertexOffset[k] : vertexOffset[k]);
  }
  /// The instance's own index of global triangle g.
  uint32_t localTriangle(uint32_t g) const {
    const uint32_t k = meshOfTri[g];
    return g - (g >= frontTriangles ? backTriOffset[k] : triOffset[k]);
  }
};

Layout makeLayout(const Scene& scene);

// A front-face hit kept for the bounces: 8 bytes.
struct HitRecord {
  uint32_t tri;     // global triangle
  uint16_t b1, b2;  // barycentrics of its 2nd and 3rd vertex, 16-bit fixed point
};

}  // namespace prt::bake
