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

// The base colours of one vertex's hit records on instances whose colour varies over their
// surface (textured or vertex-coloured), in the records' order: start() on the vertex's records,
// then next() for each such record. They are looked up kWindow at a time (AlbedoLookup::atMany:
// eight at a time with AVX-512), the barycentrics dequantised as the gathers do. A thread's
// scratch, kept from vertex to vertex (kWindow · 32 bytes, whatever the sample count).
class VaryingColours {
public:
  static constexpr uint32_t kWindow = 4096;
  void start(const AlbedoLookup& albedo, const Layout& lay, const HitRecord* hits, uint32_t first, uint32_t last) {
    albedo_ = &albedo, lay_ = &lay, hits_ = hits, scan_ = first, last_ = last, at_ = count_ = 0;
  }
  const glm::vec3& next() {
    if (at_ == count_) fill();
    return rgb_[at_++];
  }

private:
  void fill() {
    if (mesh_.empty()) {
      for (auto* v : {&mesh_, &tri_}) v->resize(kWindow);
      for (auto* v : {&b1_, &b2_}) v->resize(kWindow);
      rgb_.resize(kWindow);
    }
    at_ = count_ = 0;
    for (; scan_ < last_ && count_ < kWindow; ++scan_) {
      const HitRecord& rec = hits_[scan_];
      const uint32_t m = lay_->meshOfTri[rec.tri];
      if (albedo_->uniform[m]) continue;
      mesh_[count_] = m, tri_[count_] = lay_->localTriangle(rec.tri);
      b1_[count_] = rec.b1 * (1.0f / 65535.0f), b2_[count_] = rec.b2 * (1.0f / 65535.0f);
      ++count_;
    }
    albedo_->atMany(mesh_.data(), tri_.data(), b1_.data(), b2_.data(), count_, rgb_.data());
  }
  const AlbedoLookup* albedo_ = nullptr;
  const Layout* lay_ = nullptr;
  const HitRecord* hits_ = nullptr;
  uint32_t scan_ = 0, last_ = 0, at_ = 0, count_ = 0;
  std::vector<uint32_t> mesh_, tri_;
  std::vector<float> b1_, b2_;
  std::vector<glm::vec3> rgb_;
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
