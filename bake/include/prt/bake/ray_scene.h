// Ray casting against a Scene's triangles. The only interface to Embree in prt: every rtc*
// call lives in ray_scene.cpp, so no Embree type appears here.
#pragma once

#include <cstdint>
#include <memory>

#include <glm/glm.hpp>

#include "prt/scene.h"

namespace prt::bake {

/// One ray and its hit. The layout is Embree's RTCRayHit, checked by static_assert in
/// ray_scene.cpp, so batches are traced in place without copies.
struct alignas(16) Ray {
  static constexpr uint32_t kInvalid = 0xffffffffu;
  // ray
  glm::vec3 org{0.0f};
  float tnear = 0.0f;
  glm::vec3 dir{0.0f, 0.0f, 1.0f};
  float time = 0.0f;
  float tfar = 0.0f;  // in: max distance; out (intersect): hit distance; (occluded): -inf if hit
  uint32_t mask = 0xffffffffu;
  uint32_t id = 0;
  uint32_t flags = 0;
  // hit (intersect only)
  glm::vec3 ng{0.0f};        // unnormalised geometric normal, cross(v1 - v0, v2 - v0)
  float u = 0.0f, v = 0.0f;  // barycentrics of the triangle's 2nd and 3rd vertices
  uint32_t tri = kInvalid;   // triangle index within the instance
  uint32_t mesh = kInvalid;  // index into Scene::meshes, kInvalid on a miss
  uint32_t inst = kInvalid;

  /// Every field as a fresh Ray{} from org towards dir over [tn, tf], written one by one: a Ray
  /// built aside and copied whole is written in 4-byte parts and read back in 16-byte ones, a
  /// store-forwarding stall that cost more than making the direction.
  void start(const glm::vec3& o, const glm::vec3& d, float tn, float tf) {
    org.x = o.x, org.y = o.y, org.z = o.z;
    tnear = tn;
    dir.x = d.x, dir.y = d.y, dir.z = d.z;
    time = 0.0f;
    tfar = tf;
    mask = 0xffffffffu;
    id = flags = 0;
    ng.x = ng.y = ng.z = 0.0f;
    u = v = 0.0f;
    tri = mesh = inst = kInvalid;
  }

  bool hit() const { return mesh != kInvalid; }
  bool occludedHit() const { return tfar < 0.0f; }
  /// True when the ray hit the back of the triangle (geometric normal along the ray).
  bool backface() const { return glm::dot(ng, dir) > 0.0f; }
};

/// Eight rays and their hits, lane l of each field: Embree's RTCRayHit8, checked by
/// static_assert in ray_scene.cpp, so packets are traced in place. Lanes past the count given to
/// RayScene::intersect8 are not traced (their contents do not matter).
struct alignas(32) RayPacket8 {
  float orgX[8], orgY[8], orgZ[8], tnear[8];
  float dirX[8], dirY[8], dirZ[8], time[8];
  float tfar[8];  // in: max distance; out: hit distance
  uint32_t mask[8], id[8], flags[8];
  float ngX[8], ngY[8], ngZ[8];  // unnormalised geometric normal
  float u[8], v[8];
  uint32_t tri[8];   // triangle index within the instance
  uint32_t mesh[8];  // index into Scene::meshes, Ray::kInvalid on a miss
  uint32_t inst[8];

  /// Lane l as Ray::start: from o towards d over [tn, tf].
  void start(int l, const glm::vec3& o, const glm::vec3& d, float tn, float tf) {
    orgX[l] = o.x, orgY[l] = o.y, orgZ[l] = o.z;
    tnear[l] = tn;
    dirX[l] = d.x, dirY[l] = d.y, dirZ[l] = d.z;
    time[l] = 0.0f;
    tfar[l] = tf;
    mask[l] = 0xffffffffu;
    id[l] = flags[l] = 0;
    ngX[l] = ngY[l] = ngZ[l] = 0.0f;
    u[l] = v[l] = 0.0f;
    tri[l] = mesh[l] = inst[l] = Ray::kInvalid;
  }
  /// All 8 lanes as start(l, o, {dx[l], dy[l], dz[l]}, tn, tf), field by field: a few vector
  /// stores where eight start() calls write each lane apart.
  void startAll(const glm::vec3& o, const float* dx, const float* dy, const float* dz, float tn, float tf) {
    for (int l = 0; l < 8; ++l) orgX[l] = o.x;
    for (int l = 0; l < 8; ++l) orgY[l] = o.y;
    for (int l = 0; l < 8; ++l) orgZ[l] = o.z;
    for (int l = 0; l < 8; ++l) tnear[l] = tn;
    for (int l = 0; l < 8; ++l) dirX[l] = dx[l];
    for (int l = 0; l < 8; ++l) dirY[l] = dy[l];
    for (int l = 0; l < 8; ++l) dirZ[l] = dz[l];
    for (int l = 0; l < 8; ++l) time[l] = 0.0f;
    for (int l = 0; l < 8; ++l) tfar[l] = tf;
    for (int l = 0; l < 8; ++l) mask[l] = 0xffffffffu;
    for (int l = 0; l < 8; ++l) id[l] = flags[l] = 0;
    for (int l = 0; l < 8; ++l) ngX[l] = ngY[l] = ngZ[l] = 0.0f;
    for (int l = 0; l < 8; ++l) u[l] = v[l] = 0.0f;
    for (int l = 0; l < 8; ++l) tri[l] = mesh[l] = inst[l] = Ray::kInvalid;
  }
  /// The next eight rays from the same origin, in a packet startAll (or start, lane by lane) set
  /// and a trace has used since: only what the trace changed and the next reads is written again
  /// (the directions, tfar, and the normal, which a miss leaves as an earlier hit wrote it; the
  /// trace sets mesh and inst itself, and u, v and tri are read only where a ray hit).
  void restart(const float* dx, const float* dy, const float* dz, float tf) {
    for (int l = 0; l < 8; ++l) dirX[l] = dx[l];
    for (int l = 0; l < 8; ++l) dirY[l] = dy[l];
    for (int l = 0; l < 8; ++l) dirZ[l] = dz[l];
    for (int l = 0; l < 8; ++l) tfar[l] = tf;
    for (int l = 0; l < 8; ++l) ngX[l] = ngY[l] = ngZ[l] = 0.0f;
  }
  glm::vec3 dir(int l) const { return {dirX[l], dirY[l], dirZ[l]}; }
  bool hit(int l) const { return mesh[l] != Ray::kInvalid; }
  /// As Ray::backface, with the same arithmetic.
  bool backface(int l) const { return glm::dot(glm::vec3(ngX[l], ngY[l], ngZ[l]), dir(l)) > 0.0f; }
};

class RayScene {
 public:
  /// Builds a BVH over the scene's non-receiver instances (geometry ids = instance indices).
  /// `includeReceivers` adds receiver-only instances too. Instances that may let light through
  /// (passesLight: MASK or BLEND alpha below the cutoff or 1 somewhere, transmission) are cut
  /// out or partial occluders (opacityAt at the hit, a deterministic per-ray coin for partial
  /// opacity; ray_scene.cpp); their hits read `scene`, which must then outlive the RayScene.
  explicit RayScene(const Scene& scene, bool includeReceivers = false);
  ~RayScene();
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;

  /// Closest hits of n rays, traced as one stream. `coherent`: rays share an origin *and* a
  /// direction (a frustum, as camera rays); rays of one origin spread over a hemisphere or a
  /// sphere, as the bake's, are incoherent in Embree's sense and trace ~1.6× faster so
  /// (docs/bake.md, "Speed"). Thread-safe.
  void intersect(Ray* rays, size_t n, bool coherent = false) const;
  /// Any-hit visibility of n rays (sets tfar = -inf where occluded). Thread-safe.
  void occluded(Ray* rays, size_t n, bool coherent = false) const;
  /// Closest hits of the first n rays of packets[0 .. ceil(n / 8)), traced as packets of 8 with
  /// the incoherent flag: the fastest of Embree's ways for rays of one origin spread over a
  /// sphere (bench/embree_ceiling.cpp measures them all; docs/bake.md, "Speed"). The same hits
  /// as intersect(). Thread-safe.
  void intersect8(RayPacket8* packets, size_t n) const;

  /// Bounding-box diagonal of the traced geometry, for ray offsets.
  float sceneExtent() const { return extent_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  float extent_ = 1.0f;
};

/// One RayScene for the stages of a bake that trace the same scene, built when the first of
/// them asks (the surface bake's direct pass, then the probe bake: one BVH build instead of
/// two; a resumed bake past the direct pass builds it for the probes). The scene must outlive
/// it unchanged. Not thread-safe: the stages' own thread asks, before it starts their workers.
class SharedRayScene {
 public:
  explicit SharedRayScene(const Scene& scene) : scene_(scene) {}
  const RayScene& get() {
    if (!rays_) rays_ = std::make_unique<RayScene>(scene_);
    return *rays_;
  }
  /// Frees the BVH (the last stage that traces is done with it); get() would build it again.
  void release() { rays_.reset(); }

 private:
  const Scene& scene_;
  std::unique_ptr<RayScene> rays_;
};

}  // namespace prt::bake
