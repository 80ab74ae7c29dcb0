// Where a baked point's rays start and which directions they take: shared by the surface bake
// (surface_bake.cpp) and the refinement that decides where the bake needs vertices
// (refine.cpp), so that refinement measures transfer with the bake's own estimator.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/ray_scene.h"
#include "prt/bake/sampling.h"

namespace prt::bake {

// Ray j of vertex v, exactly as the bake casts it.
struct VertexSampler {
  glm::vec3 origin;
  Frame frame;
  uint32_t s0, s1;
  float tnear;
  VertexSampler(const glm::vec3& org, const glm::vec3& n, uint64_t seed, size_t v, float tn)
      : origin(org), frame(Frame::fromNormal(n)), tnear(tn) {
    const uint64_t h = splitMix64(seed ^ splitMix64(v));
    s0 = uint32_t(h);
    s1 = uint32_t(h >> 32);
  }
  void make(uint32_t j, Ray& ray) const {
    ray.start(origin, frame.toWorld(sampleCosineHemisphere({sobol0(j, s0), sobol1(j, s1)})), tnear,
              std::numeric_limits<float>::infinity());
  }
};

inline float tnearFor(float extent) { return 1e-6f * extent; }
// How far a ray origin is lifted off its surface (liftedOrigin; unbury.h moves a buried one that
// far past the surface that buries it).
inline float liftFor(float extent) { return 1e-4f * extent; }

// A vertex lies on its own triangles and, at a corner of a room, on the plane of the next wall
// too: a ray leaving exactly there can slip through that wall and see the sky. The origin is
// therefore lifted along the normal *and* pulled towards the centroids of the vertex's
// triangles, by a small fraction of the scene size. accumulatePull adds, per corner of every
// triangle of one mesh, the unit vector towards the triangle's centroid to pull[corner].
inline void accumulatePull(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& indices,
                           glm::vec3* pull) {
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    const uint32_t* ix = &indices[t];
    const glm::vec3 c = (positions[ix[0]] + positions[ix[1]] + positions[ix[2]]) / 3.0f;
    for (int j = 0; j < 3; ++j) {
      const glm::vec3 d = c - positions[ix[j]];
      const float len = glm::length(d);
      if (len > 0.0f) pull[ix[j]] += d / len;
    }
  }
}

// The ray origin of a point at `p` with unit normal `n` and summed pull `pull`.
inline glm::vec3 liftedOrigin(const glm::vec3& p, const glm::vec3& n, glm::vec3 pull, float extent) {
  const float len = glm::length(pull);
  if (len > 0.0f) pull /= len;
  return p + liftFor(extent) * (n + pull);
}

}  // namespace prt::bake
