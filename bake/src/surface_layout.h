// The global numbering of a surface bake's vertices and triangles (both sides), where their
// rays start and what a hit keeps: shared by the surface bake (surface_bake.cpp) and the gather
// of direct lights' bounced light at relight time (direct_bounce.cpp), which must cast the
// bake's own rays and read its hits the same way.
#pragma once

#include <cstddef>
#include <cstdint>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "albedo_lookup.h"
#include "prt/bake/ray_scene.h"
#include "prt/scene.h"

namespace prt::bake {

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
  std::vector<uint32_t> triVerts;    // global triangle -> 3 global vertex indices
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

// Where rays of each vertex start (vertex_rays.h: lifted along the normal, pulled towards
// the centroids of the vertex's triangles). A virtual vertex (a back side) is lifted along −n
// instead, with the same pull.
std::vector<glm::vec3> rayOrigins(const Scene& scene, const Layout& lay, float extent);

// The side's normal: a virtual vertex faces away from its vertex's normal.
glm::vec3 normalOf(const Scene& scene, const Layout& lay, size_t v);

// A front-face hit kept for the bounces: 8 bytes.
struct HitRecord {
  uint32_t tri;     // global triangle
  uint16_t b1, b2;  // barycentrics of its 2nd and 3rd vertex, 16-bit fixed point
};

// The base colours of hit records [first, last) (one vertex's) on instances whose colour varies
// over their surface (textured or vertex-coloured), looked up together (AlbedoLookup::atMany:
// eight at a time with AVX-512), in the records' order; the barycentrics as the gathers
// dequantise them. A thread's scratch, kept from vertex to vertex.
struct VaryingColours {
  std::vector<uint32_t> mesh, tri;
  std::vector<float> b1, b2;
  std::vector<glm::vec3> rgb;
  const glm::vec3* lookUp(const AlbedoLookup& albedo, const Layout& lay, const HitRecord* hits, uint32_t first,
                          uint32_t last) {
    if (mesh.size() < last - first) {
      for (auto* v : {&mesh, &tri}) v->resize(last - first);
      for (auto* v : {&b1, &b2}) v->resize(last - first);
      rgb.resize(last - first);
    }
    uint32_t n = 0;
    for (uint32_t h = first; h < last; ++h) {
      const uint32_t m = lay.meshOfTri[hits[h].tri];
      if (albedo.uniform[m]) continue;
      mesh[n] = m, tri[n] = lay.localTriangle(hits[h].tri);
      b1[n] = hits[h].b1 * (1.0f / 65535.0f), b2[n] = hits[h].b2 * (1.0f / 65535.0f);
      ++n;
    }
    albedo.atMany(mesh.data(), tri.data(), b1.data(), b2.data(), n, rgb.data());
    return rgb.data();
  }
};

inline uint16_t quantise(float b) {
  return static_cast<uint16_t>(std::lround(std::clamp(b, 0.0f, 1.0f) * 65535.0f));
}

// Hit records of one chunk of vertices, CSR: hits of vertex v are [begin[v], begin[v+1]).
struct ChunkHits {
  std::vector<HitRecord> hits;
  std::vector<uint32_t> begin;
};

// The triangle a hit records, or kNone when the hit sends nothing: a front face is the real
// triangle, the back of a double-sided face its virtual triangle, the back of a one-sided face
// nothing.
inline uint32_t recordedTriangle(const Layout& lay, const Ray& ray) {
  if (!ray.backface()) return lay.triOffset[ray.mesh] + ray.tri;
  const uint32_t b = lay.backTriOffset[ray.mesh];
  return b == Layout::kNone ? Layout::kNone : b + ray.tri;
}

}  // namespace prt::bake
