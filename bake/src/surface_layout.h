// Where the rays of a surface bake's vertices start (their numbering: prt/bake/surface_layout.h)
// and how a hit is kept: shared by the surface bake (surface_bake.cpp) and the gather
// of direct lights' bounced light at relight time (direct_bounce.cpp), which must cast the
// bake's own rays and read its hits the same way.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/albedo_lookup.h"
#include "prt/bake/direct_light.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/surface_bake.h"
#include "prt/bake/surface_layout.h"
#include "prt/scene.h"
#include "vertex_rays.h"

namespace prt::bake {

// Where rays of each vertex start (vertex_rays.h: lifted along the normal, pulled towards
// the centroids of the vertex's triangles; a buried vertex moved out along its own triangles,
// unbury.h). A virtual vertex (a back side) is lifted along −n instead, with the same pull.
std::vector<glm::vec3> rayOrigins(const Scene& scene, const Layout& lay, const RayScene& rays);

// The side's normal: a virtual vertex faces away from its vertex's normal.
glm::vec3 normalOf(const Scene& scene, const Layout& lay, size_t v);

// Irradiance per instance and side (DirectIrradiance's layout) as one value per vertex side of
// the layout; a side without values is zero.
std::vector<glm::vec3> sideValues(const Scene& scene, const Layout& lay, const DirectIrradiance& d);

// One value per vertex side back in DirectIrradiance's layout: for the sides `like` holds values
// for, or, without `like`, for the instances that hold transfer (their back sides where they
// hold back-side transfer).
DirectIrradiance perInstance(const Scene& scene, const Layout& lay, const std::vector<glm::vec3>& values,
                             const DirectIrradiance* like = nullptr);

inline uint16_t quantise(float b) { return static_cast<uint16_t>(std::lround(std::clamp(b, 0.0f, 1.0f) * 65535.0f)); }

// Hit records of one chunk of vertices, CSR: hits of vertex v are [begin[v], begin[v+1]).
struct ChunkHits {
  std::vector<HitRecord> hits;
  std::vector<uint32_t> begin;
  // With BakeSettings::keepGatherRays: per vertex of the chunk, its first rays' escape and
  // record bits (GatherRecords::Chunk::bits); empty for a chunk restored from a checkpoint.
  std::vector<uint64_t> gatherBits;
};

// The triangle a hit records, or kNone when the hit sends nothing: a front face is the real
// triangle, the back of a double-sided face its virtual triangle, the back of a one-sided face
// nothing.
inline uint32_t recordedTriangle(const Layout& lay, const Ray& ray) {
  if (!ray.backface()) return lay.triOffset[ray.mesh] + ray.tri;
  const uint32_t b = lay.backTriOffset[ray.mesh];
  return b == Layout::kNone ? Layout::kNone : b + ray.tri;
}

// A vertex side's first K gather rays, exactly as the bake casts them (`sampler`), traced in
// streams: escaped(j, ray) for each ray that leaves the scene, hit(triangle, b1, b2) for each
// one that lands on a recorded triangle (recordedTriangle; barycentrics quantised as a
// HitRecord keeps them). The gather at relight time and the bounce operator read them so.
template <class Escaped, class Hit>
void traceGatherRays(const RayScene& rays, const Layout& lay, const VertexSampler& sampler, uint32_t K,
                     Escaped&& escaped, Hit&& hit) {
  constexpr uint32_t kStream = 256;
  alignas(64) Ray batch[kStream];
  for (uint32_t first = 0; first < K; first += kStream) {
    const uint32_t count = std::min(kStream, K - first);
    for (uint32_t j = 0; j < count; ++j) sampler.make(first + j, batch[j]);
    rays.intersect(batch, count);
    for (uint32_t j = 0; j < count; ++j) {
      const Ray& r = batch[j];
      if (!r.hit()) {
        escaped(first + j, r);
        continue;
      }
      const uint32_t tri = recordedTriangle(lay, r);
      if (tri != Layout::kNone) hit(tri, quantise(r.u), quantise(r.v));
    }
  }
}

// The same calls, in the same order, from vertex side v's kept rays (GatherRecords, of the
// same K rays): an escaped ray is made again for its direction, a recorded one read back, so
// nothing is traced.
template <class Escaped, class Hit>
void replayGatherRays(const GatherRecords& kept, size_t v, const VertexSampler& sampler, Escaped&& escaped, Hit&& hit) {
  const GatherRecords::Chunk& c = *kept.of(v);
  const size_t i = v % kept.chunk;
  const uint64_t* escapedBits = &c.bits[i * 2 * kept.words];
  const uint64_t* recordedBits = escapedBits + kept.words;
  const HitRecord* next = c.hits.data() + c.begin[i];
  Ray ray;
  for (uint32_t j = 0; j < kept.rays; ++j) {
    const uint64_t bit = uint64_t(1) << (j % 64);
    if (escapedBits[j / 64] & bit) {
      sampler.make(j, ray);
      escaped(j, ray);
    } else if (recordedBits[j / 64] & bit) {
      hit(next->tri, next->b1, next->b2);
      ++next;
    }
  }
}

}  // namespace prt::bake
