// One value per baked vertex side, in DirectIrradiance's layout (prt/bake/direct_light.h): the
// direct lights' and the lights inside the scene's shadowed irradiance at the vertices
// (direct_light.cpp, local_lights.cpp) walk the sides alike. Private to prt::bake.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prt/bake/direct_light.h"
#include "prt/scene.h"
#include "unbury.h"
#include "vertex_rays.h"

namespace prt::bake {

/// `at(position, origin, normal, index, rays)` at every vertex side of the instances with
/// transfer (front sides of every instance in scene order, then the back sides of those with
/// back-side transfer: `index` numbers them so): its ray origin lifted off the surface
/// (liftedOrigin; a front side moved out where it is buried: unbury.h), its normal (−n on a back side); `at` returns the side's irradiance (double
/// RGB) and adds the rays it traced to `rays`. Fills `rays` and `seconds` (from `t0`).
/// `origins` (if given): the sides' ray origins in that numbering (rayOrigins, which numbers the
/// baked sides alike), kept by a caller that lights many frames, so that the buried sides' test
/// is not traced again each time.
template <class At>
DirectIrradiance perVertexSide(const Scene& scene, const RayScene& rays, std::chrono::steady_clock::time_point t0,
                               At&& at, const std::vector<glm::vec3>* origins = nullptr) {
  const float extent = rays.sceneExtent();
  DirectIrradiance out;
  out.front.resize(scene.meshes.size());
  out.back.resize(scene.meshes.size());
  std::atomic<uint64_t> traced{0};
  size_t firstVertex = 0;
  for (int side = 0; side < 2; ++side)
    for (size_t k = 0; k < scene.meshes.size(); ++k) {
      const MeshInstance& m = scene.meshes[k];
      if (m.transfer.empty() || (side == 1 && !m.hasBackTransfer())) continue;
      std::vector<glm::vec3> pull;
      std::optional<FanTargets> fans;
      if (!origins) {
        pull.assign(m.vertexCount(), glm::vec3(0.0f));
        accumulatePull(m.positions, m.indices, pull.data());
        fans.emplace(m.positions, m.indices);
      }
      std::vector<glm::vec3>& result = side == 0 ? out.front[k] : out.back[k];
      result.assign(m.vertexCount(), glm::vec3(0.0f));
      const size_t base = firstVertex;
      tbb::parallel_for(tbb::blocked_range<size_t>(0, m.vertexCount(), 64), [&](const tbb::blocked_range<size_t>& r) {
        uint64_t count = 0;
        for (size_t v = r.begin(); v < r.end(); ++v) {
          const glm::vec3 n = side == 0 ? m.normals[v] : -m.normals[v];
          glm::vec3 origin;
          if (origins) {
            origin = (*origins)[base + v];
          } else {
            const glm::vec3 lifted = liftedOrigin(m.positions[v], n, pull[v], extent);
            origin = side == 0 ? unburiedOrigin(rays, m.positions[v], n, lifted, fans->of(v), extent) : lifted;
          }
          result[v] = glm::vec3(at(m.positions[v], origin, n, base + v, count));
        }
        traced += count;
      });
      firstVertex += m.vertexCount();
    }
  out.rays = traced;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace prt::bake
