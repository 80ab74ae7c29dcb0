// Scenes built in memory for the tests: no file, no loader, exactly known geometry.
#pragma once

#include <cmath>

#include "prt/math.h"
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
    double theta = opening + (prt::kPi - opening) * double(r) / rings;
    for (int s = 0; s < segments; ++s) {
      double phi = 2.0 * prt::kPi * s / segments;
      glm::vec3 p(float(std::sin(theta) * std::cos(phi)), float(std::cos(theta)),
                  float(std::sin(theta) * std::sin(phi)));
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

/// A scene of the given instances with one grey material of albedo `rho` each (a dielectric:
/// metallicFactor 0, where glTF's default is 1).
inline Scene makeScene(std::vector<MeshInstance> meshes, float rho) {
  Scene s;
  s.path = "memory";
  Material mat;
  mat.baseColorFactor = glm::vec4(rho, rho, rho, 1.0f);
  mat.metallicFactor = 0.0f;
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

// Builders added later (kept below the first block so merges stay clean).
#include <algorithm>
#include <string>
#include <vector>

namespace prt::test {

/// A solid axis-aligned box [lo, hi] (outward faces, so it is seen from outside as front faces
/// and from inside as back faces), each face subdivided into squares of side about `cell`
/// (0: one quad per face), so per-vertex transfer has vertices across the face.
// A rectangle p0 + s·du + t·dv (s, t in [0, 1]) in nu × nv quads, normal du × dv (counter-clockwise
// seen from the normal's side).
inline MeshInstance makeQuad(const std::string& name, glm::vec3 p0, glm::vec3 du, glm::vec3 dv, int nu, int nv) {
  MeshInstance m;
  m.name = name;
  const glm::vec3 n = glm::normalize(glm::cross(du, dv));
  for (int j = 0; j <= nv; ++j)
    for (int i = 0; i <= nu; ++i) {
      m.positions.push_back(p0 + du * (float(i) / nu) + dv * (float(j) / nv));
      m.normals.push_back(n);
    }
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const uint32_t a = uint32_t(j * (nu + 1) + i), b = a + 1, c = a + uint32_t(nu) + 2, d = a + uint32_t(nu) + 1;
      m.indices.insert(m.indices.end(), {a, b, c, a, c, d});
    }
  return m;
}

inline MeshInstance makeSlab(const glm::vec3& lo, const glm::vec3& hi, float cell = 0.0f) {
  MeshInstance m;
  m.name = "slab";
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      glm::vec3 n(0.0f);
      n[axis] = side ? 1.0f : -1.0f;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const int nu = cell > 0.0f ? std::max(1, int(std::ceil((hi[u] - lo[u]) / cell))) : 1;
      const int nv = cell > 0.0f ? std::max(1, int(std::ceil((hi[v] - lo[v]) / cell))) : 1;
      const uint32_t base = uint32_t(m.positions.size());
      for (int j = 0; j <= nv; ++j)
        for (int i = 0; i <= nu; ++i) {
          glm::vec3 p;
          p[axis] = side ? hi[axis] : lo[axis];
          p[u] = lo[u] + (hi[u] - lo[u]) * float(i) / float(nu);
          p[v] = lo[v] + (hi[v] - lo[v]) * float(j) / float(nv);
          m.positions.push_back(p);
          m.normals.push_back(n);
        }
      for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
          const uint32_t a = base + uint32_t(j * (nu + 1) + i), b = a + 1, c = a + uint32_t(nu + 1), d = c + 1;
          addTriangle(m, a, b, d, n);
          addTriangle(m, a, d, c, n);
        }
    }
  return m;
}

/// Two rooms side by side along x, 3 m high and 3 m deep (z ∈ [0, 3]), for light-leak tests:
/// a bright room x ∈ [0, wallX] open to the sky (no ceiling) and a dark room
/// x ∈ [wallX + thickness, 6] closed on every side, so no light reaches it at all. Between them a
/// thin wall x ∈ [wallX, wallX + thickness] from the floor to the dark room's ceiling. Every part
/// is a solid slab 0.2 m thick; slabs overlap at the edges so no ray slips through a seam, and
/// each room has its own slabs (split inside the thin wall), so per-vertex transfer never
/// interpolates across the wall. Faces are subdivided into squares of about `cell`.
inline std::vector<MeshInstance> makeTwoRooms(float wallX, float thickness, float cell) {
  const float t = 0.2f, mid = wallX + 0.5f * thickness;
  std::vector<MeshInstance> m;
  // Bright room: floor, the far wall x = 0, the side walls z = 0 and z = 3, no ceiling.
  m.push_back(makeSlab({-t, -t, -t}, {mid, 0.0f, 3.0f + t}, cell));
  m.push_back(makeSlab({-t, 0.0f, -t}, {0.0f, 3.0f, 3.0f + t}, cell));
  m.push_back(makeSlab({0.0f, 0.0f, -t}, {mid, 3.0f, 0.0f}, cell));
  m.push_back(makeSlab({0.0f, 0.0f, 3.0f}, {mid, 3.0f, 3.0f + t}, cell));
  // Dark room: floor, ceiling, the far wall x = 6, the side walls.
  m.push_back(makeSlab({mid, -t, -t}, {6.0f + t, 0.0f, 3.0f + t}, cell));
  m.push_back(makeSlab({mid, 3.0f, -t}, {6.0f + t, 3.0f + t, 3.0f + t}, cell));
  m.push_back(makeSlab({6.0f, 0.0f, -t}, {6.0f + t, 3.0f, 3.0f + t}, cell));
  m.push_back(makeSlab({mid, 0.0f, -t}, {6.0f, 3.0f, 0.0f}, cell));
  m.push_back(makeSlab({mid, 0.0f, 3.0f}, {6.0f, 3.0f, 3.0f + t}, cell));
  // The thin wall, up to the top of the dark room's ceiling.
  m.push_back(makeSlab({wallX, -t, -t}, {wallX + thickness, 3.0f + t, 3.0f + t}, cell));
  return m;
}

// The room of the bounce operator's tests: a cavity and a slab in it, double-sided, albedo
// (0.8, 0.6, 0.4).
inline Scene makeColouredRoom(int rings = 12, int segments = 24) {
  Scene s = makeScene(
      {makeCavity(kPi / 2.5, rings, segments), makeSlab({-0.3f, -0.9f, -0.3f}, {0.3f, -0.7f, 0.3f}, 0.1f)}, 0.7f);
  for (Material& m : s.materials) {
    m.doubleSided = true;
    m.baseColorFactor = glm::vec4(0.8f, 0.6f, 0.4f, 1.0f);
  }
  return s;
}

}  // namespace prt::test
