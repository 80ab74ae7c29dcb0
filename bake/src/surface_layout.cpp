#include "surface_layout.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prt/error.h"
#include "unbury.h"
#include "vertex_rays.h"

namespace prt::bake {

bool bakesBackSide(const Scene& scene, const MeshInstance& m) {
  return !m.receiverOnly && m.material >= 0 && size_t(m.material) < scene.materials.size() &&
         scene.materials[size_t(m.material)].doubleSided;
}

Layout makeLayout(const Scene& scene) {
  Layout lay;
  lay.vertexOffset.assign(scene.meshes.size(), SIZE_MAX);
  lay.backVertexOffset.assign(scene.meshes.size(), SIZE_MAX);
  lay.triOffset.assign(scene.meshes.size(), 0);
  lay.backTriOffset.assign(scene.meshes.size(), Layout::kNone);
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    lay.triOffset[k] = static_cast<uint32_t>(lay.triangles);
    if (m.receiverOnly) continue;
    lay.vertexOffset[k] = lay.vertices;
    lay.vertices += m.vertexCount();
    lay.triangles += m.triangleCount();
  }
  lay.frontVertices = lay.vertices;
  lay.frontTriangles = lay.triangles;
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if (!bakesBackSide(scene, m)) continue;
    lay.backVertexOffset[k] = lay.vertices;
    lay.backTriOffset[k] = static_cast<uint32_t>(lay.triangles);  // overflow refused below
    lay.vertices += m.vertexCount();
    lay.triangles += m.triangleCount();
  }
  if (lay.triangles >= std::numeric_limits<uint32_t>::max() || lay.vertices >= std::numeric_limits<uint32_t>::max())
    throw Error(
        cat("scene too large: ", lay.triangles, " triangles, ", lay.vertices, " vertices (at most 2^32 - 1 each)"));
  lay.meshOfVertex.resize(lay.vertices);
  lay.triVerts.resize(lay.triangles * 3);
  lay.meshOfTri.resize(lay.triangles);
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if (m.receiverOnly) continue;
    size_t v0 = lay.vertexOffset[k];
    std::fill_n(lay.meshOfVertex.begin() + v0, m.vertexCount(), uint32_t(k));
    for (size_t t = 0; t < m.triangleCount(); ++t) {
      size_t g = lay.triOffset[k] + t;
      lay.meshOfTri[g] = uint32_t(k);
      for (int c = 0; c < 3; ++c) lay.triVerts[3 * g + c] = uint32_t(v0 + m.indices[3 * t + c]);
    }
    if (lay.backVertexOffset[k] == SIZE_MAX) continue;
    // The back side: the same corners, in the same order (so a hit's barycentrics are the
    // same), numbered as virtual vertices.
    const size_t b0 = lay.backVertexOffset[k];
    std::fill_n(lay.meshOfVertex.begin() + b0, m.vertexCount(), uint32_t(k));
    for (size_t t = 0; t < m.triangleCount(); ++t) {
      size_t g = lay.backTriOffset[k] + t;
      lay.meshOfTri[g] = uint32_t(k);
      for (int c = 0; c < 3; ++c) lay.triVerts[3 * g + c] = uint32_t(b0 + m.indices[3 * t + c]);
    }
  }
  return lay;
}

std::vector<glm::vec3> rayOrigins(const Scene& scene, const Layout& lay, const RayScene& rays) {
  const float extent = rays.sceneExtent();
  std::vector<glm::vec3> origins(lay.vertices);
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if (m.receiverOnly) continue;
    std::vector<glm::vec3> pull(m.vertexCount(), glm::vec3(0.0f));  // a back side shares its vertex's pull
    accumulatePull(m.positions, m.indices, pull.data());
    const FanTargets fans(m.positions, m.indices);
    const size_t v0 = lay.vertexOffset[k], b0 = lay.backVertexOffset[k];
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m.vertexCount(), 256), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) {
        const glm::vec3& p = m.positions[i];
        const glm::vec3& n = m.normals[i];
        origins[v0 + i] = unburiedOrigin(rays, p, n, liftedOrigin(p, n, pull[i], extent), fans.of(i), extent);
        if (b0 != SIZE_MAX) origins[b0 + i] = liftedOrigin(p, -n, pull[i], extent);  // back sides stay (unbury.h)
      }
    });
  }
  return origins;
}

glm::vec3 normalOf(const Scene& scene, const Layout& lay, size_t v) {
  const glm::vec3& n = scene.meshes[lay.meshOfVertex[v]].normals[lay.localVertex(v)];
  return lay.isBack(v) ? -n : n;
}

std::vector<glm::vec3> sideValues(const Scene& scene, const Layout& lay, const DirectIrradiance& d) {
  PRT_CHECK_EQ(d.front.size(), scene.meshes.size());
  PRT_CHECK_EQ(d.back.size(), scene.meshes.size());
  std::vector<glm::vec3> out(lay.vertices, glm::vec3(0.0f));
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    if (lay.vertexOffset[k] == SIZE_MAX) continue;
    const size_t n = scene.meshes[k].vertexCount();
    if (d.front[k].size() == n)
      std::copy(d.front[k].begin(), d.front[k].end(), out.begin() + ptrdiff_t(lay.vertexOffset[k]));
    if (lay.backVertexOffset[k] != SIZE_MAX && d.back[k].size() == n)
      std::copy(d.back[k].begin(), d.back[k].end(), out.begin() + ptrdiff_t(lay.backVertexOffset[k]));
  }
  return out;
}

DirectIrradiance perInstance(const Scene& scene, const Layout& lay, const std::vector<glm::vec3>& values,
                             const DirectIrradiance* like) {
  DirectIrradiance out;
  out.front.resize(scene.meshes.size());
  out.back.resize(scene.meshes.size());
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if (lay.vertexOffset[k] == SIZE_MAX) continue;
    const size_t n = m.vertexCount();
    const bool front = like ? like->front[k].size() == n : !m.transfer.empty();
    const bool back = lay.backVertexOffset[k] != SIZE_MAX &&
                      (like ? like->back[k].size() == n : !m.transfer.empty() && m.hasBackTransfer());
    if (front) {
      const auto at = values.begin() + ptrdiff_t(lay.vertexOffset[k]);
      out.front[k].assign(at, at + ptrdiff_t(n));
    }
    if (back) {
      const auto at = values.begin() + ptrdiff_t(lay.backVertexOffset[k]);
      out.back[k].assign(at, at + ptrdiff_t(n));
    }
  }
  return out;
}

}  // namespace prt::bake
