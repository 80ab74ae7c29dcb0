// Scenes built in memory for the tests: no file, no loader, exactly known geometry.
#pragma once

#include <cmath>

#include "prt/scene.h"

namespace prt::test {

/// Appends a triangle, wound so that its geometric normal points along `facing`.
inline void addTriangle(MeshInstance& m, uint32_t a, uint32_t b, uint32_t c, const glm::vec3& facing) {
  glm::vec3 n = glm::cross(m.positions[b] - m.positions[a], m.positions[c] - m.positions[a]);
  if (glm::dot(n, facing) < 0.0f) std::swap(b, c);
  m.indices.insert(m.indices.end(), {a, b, c});
}

/// A square of side `size` centred at `centre`, facing +Y, subdivided `n`×`n`.
inline MeshInstance makePlane(const glm::vec3& centre, float size, int n) {
  MeshInstance m;
  m.name = "plane";
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      m.positions.push_back(centre + glm::vec3((float(i) / n - 0.5f) * size, 0.0f, (float(j) / n - 0.5f) * size));
      m.normals.push_back({0, 1, 0});
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      uint32_t a = j * (n + 1) + i, b = a + 1, c = a + (n + 1), d = c + 1;
      addTriangle(m, a, b, d, {0, 1, 0});
      addTriangle(m, a, d, c, {0, 1, 0});
    }
  return m;
}

/// Interior of a unit sphere with a cap-shaped opening of half-angle `opening` (radians) around
/// +Y; normals point to the centre, triangles face inwards. Rings are spaced evenly in θ from
/// the opening's rim to the south pole, so the rim is exactly the first ring.
inline MeshInstance makeCavity(double opening, int rings, int segments) {
  MeshInstance m;
  m.name = "cavity";
  for (int r = 0; r < rings; ++r) {
    double theta = opening + (M_PI - opening) * double(r) / rings;
    for (int s = 0; s < segments; ++s) {
      double phi = 2.0 * M_PI * s / segments;
      glm::vec3 p(float(std::sin(theta) * std::cos(phi)), float(std::cos(theta)), float(std::sin(theta) * std::sin(phi)));
      m.positions.push_back(p);
      m.normals.push_back(-p);
    }
  }
  uint32_t pole = uint32_t(m.positions.size());
  m.positions.push_back({0, -1, 0});
  m.normals.push_back({0, 1, 0});
  for (int r = 0; r + 1 < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      uint32_t a = r * segments + s, b = r * segments + (s + 1) % segments;
      uint32_t c = a + segments, d = b + segments;
      glm::vec3 inward = -(m.positions[a] + m.positions[d]);
      addTriangle(m, a, b, d, inward);
      addTriangle(m, a, d, c, inward);
    }
  for (int s = 0; s < segments; ++s) {
    uint32_t a = (rings - 1) * segments + s, b = (rings - 1) * segments + (s + 1) % segments;
    addTriangle(m, a, b, pole, {0, 1, 0});
  }
  return m;
}

/// A scene of the given instances with one grey material of albedo `rho` each.
inline Scene makeScene(std::vector<MeshInstance> meshes, float rho) {
  Scene s;
  s.path = "memory";
  Material mat;
  mat.baseColorFactor = glm::vec4(rho, rho, rho, 1.0f);
  s.materials.push_back(mat);
  s.boundsMin = glm::vec3(1e30f);
  s.boundsMax = glm::vec3(-1e30f);
  for (MeshInstance& m : meshes) {
    m.material = 0;
    for (const glm::vec3& p : m.positions) {
      s.boundsMin = glm::min(s.boundsMin, p);
      s.boundsMax = glm::max(s.boundsMax, p);
    }
  }
  s.meshes = std::move(meshes);
  return s;
}

}  // namespace prt::test
