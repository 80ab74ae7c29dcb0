// One value per baked vertex side, in DirectIrradiance's layout (prt/bake/direct_light.h): the
// direct lights' and the lights inside the scene's shadowed irradiance at the vertices
// (direct_light.cpp, local_lights.cpp) walk the sides alike. Private to prt::bake.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prt/bake/direct_light.h"
#include "prt/error.h"
#include "prt/scene.h"
#include "surface_layout.h"

namespace prt::bake {

/// `at(position, origin, normal, index, rays)` at every vertex side of the instances with
/// transfer (front sides of every instance in scene order, then the back sides of those with
/// back-side transfer: `index` numbers them so): its ray origin (rayOrigins: lifted off the
/// surface, a front side moved out where it is buried, unbury.h), its normal (−n on a back
/// side); `at` returns the side's irradiance (double RGB) and adds the rays it traced to `rays`.
/// Fills `rays` and `seconds` (from `t0`). `origins` (if given): rayOrigins(scene,
/// makeLayout(scene), rays), in the layout's numbering, kept by a caller that lights many frames
/// so that the buried sides' test is not traced again each time; else made here. A side the
/// layout does not bake (back-side transfer under a single-sided material) gets no light.
template <class At>
DirectIrradiance perVertexSide(const Scene& scene, const RayScene& rays, std::chrono::steady_clock::time_point t0,
                               At&& at, const std::vector<glm::vec3>* origins = nullptr) {
  const Layout lay = makeLayout(scene);
  std::vector<glm::vec3> own;
  if (!origins) {
    own = rayOrigins(scene, lay, rays);
    origins = &own;
  }
  PRT_CHECK_EQ(origins->size(), lay.vertices);
  DirectIrradiance out;
  out.front.resize(scene.meshes.size());
  out.back.resize(scene.meshes.size());
  std::atomic<uint64_t> traced{0};
  size_t firstVertex = 0;
  for (int side = 0; side < 2; ++side)
    for (size_t k = 0; k < scene.meshes.size(); ++k) {
      const MeshInstance& m = scene.meshes[k];
      if (m.transfer.empty() || (side == 1 && !m.hasBackTransfer())) continue;
      std::vector<glm::vec3>& result = side == 0 ? out.front[k] : out.back[k];
      result.assign(m.vertexCount(), glm::vec3(0.0f));
      const size_t base = firstVertex, at0 = side == 0 ? lay.vertexOffset[k] : lay.backVertexOffset[k];
      firstVertex += m.vertexCount();
      if (at0 == SIZE_MAX) continue;
      tbb::parallel_for(tbb::blocked_range<size_t>(0, m.vertexCount(), 64), [&](const tbb::blocked_range<size_t>& r) {
        uint64_t count = 0;
        for (size_t v = r.begin(); v < r.end(); ++v) {
          const glm::vec3 n = side == 0 ? m.normals[v] : -m.normals[v];
          result[v] = glm::vec3(at(m.positions[v], (*origins)[at0 + v], n, base + v, count));
        }
        traced += count;
      });
    }
  out.rays = traced;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace prt::bake
