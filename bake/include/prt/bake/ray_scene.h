// Ray casting against a Scene's triangles. The only interface to Embree in prt: every rtc*
// call lives in ray_scene.cpp, so no Embree type appears here.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "prt/scene.h"

namespace prt::bake {

/// A batch of rays in structure-of-arrays form, traced together (one Embree stream).
/// Inputs: org, dir, tnear, tfar. Outputs of intersect(): tfar (hit distance), mesh
/// (instance index in Scene::meshes or kMiss), tri, u, v (barycentrics of vertices 2 and 3),
/// backface (geometric normal faces along the ray). Outputs of occluded(): occluded.
struct RayBatch {
  static constexpr uint32_t kMiss = 0xffffffffu;
  std::vector<glm::vec3> org, dir;
  std::vector<float> tnear, tfar;
  std::vector<uint32_t> mesh, tri;
  std::vector<float> u, v;
  std::vector<uint8_t> backface, occluded;

  size_t size() const { return org.size(); }
  void resize(size_t n);
};

class RayScene {
public:
  /// Builds a BVH over the scene's non-receiver instances (high quality build).
  /// `includeReceivers` adds receiver-only instances too (for reference renders in tests).
  explicit RayScene(const Scene& scene, bool includeReceivers = false);
  ~RayScene();
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;

  /// Closest hits for every ray of the batch. Thread-safe.
  void intersect(RayBatch& batch) const;
  /// Any-hit visibility for every ray of the batch. Thread-safe.
  void occluded(RayBatch& batch) const;

  /// Scene scale (bounding-box diagonal), for ray offsets.
  float sceneExtent() const { return extent_; }
  /// Bytes of geometry and BVH Embree holds (approximate).
  uint64_t memoryBytes() const;

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  float extent_ = 1.0f;
};

}  // namespace prt::bake
