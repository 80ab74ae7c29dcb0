// MikkTSpace tangents (prt/tangents.h gives the steps and what differs from mikktspace.c).
#include "prt/tangents.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <unordered_map>

namespace prt {

namespace {

/// Step 1: the first index of every (position, normal, uv), compared bit for bit.
std::vector<uint32_t> weldIdentical(const std::vector<glm::vec3>& p, const std::vector<glm::vec3>& n,
                                    const std::vector<glm::vec2>& uv) {
  struct Key {
    float v[8];
    bool operator==(const Key& o) const { return std::memcmp(v, o.v, sizeof v) == 0; }
  };
  struct Hash {
    size_t operator()(const Key& k) const {
      size_t h = 1469598103934665603ull;
      for (float f : k.v) {
        uint32_t bits;
        std::memcpy(&bits, &f, 4);
        h = (h ^ bits) * 1099511628211ull;
      }
      return h;
    }
  };
  std::unordered_map<Key, uint32_t, Hash> first;
  std::vector<uint32_t> canonical(p.size());
  for (size_t i = 0; i < p.size(); ++i) {
    const Key k{{p[i].x, p[i].y, p[i].z, n[i].x, n[i].y, n[i].z, uv[i].x, uv[i].y}};
    canonical[i] = first.emplace(k, uint32_t(i)).first->second;
  }
  return canonical;
}

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

/// Step 2: a triangle's tangent direction along +u (unit) and whether it preserves orientation;
/// false where its texture-space or geometric area is zero.
bool triangleTangent(const glm::dvec3 p[3], const glm::dvec2 uv[3], glm::dvec3& tangent, bool& preserving) {
  const glm::dvec3 d1 = p[1] - p[0], d2 = p[2] - p[0];
  // (u, 1 − v): MikkTSpace's t points up the image.
  const double s1 = uv[1].x - uv[0].x, t1 = -(uv[1].y - uv[0].y);
  const double s2 = uv[2].x - uv[0].x, t2 = -(uv[2].y - uv[0].y);
  const double area = s1 * t2 - s2 * t1;
  if (!(std::fabs(area) > 0.0) || !std::isfinite(area)) return false;
  const glm::dvec3 os = t2 * d1 - t1 * d2;
  const double len = glm::length(os);
  if (!(len > 0.0) || !std::isfinite(len)) return false;
  preserving = area > 0.0;
  tangent = os * ((preserving ? 1.0 : -1.0) / len);
  return true;
}

/// Step 3: the angle at corner p between the edges to a and b, in the plane of n.
double cornerAngle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& n) {
  glm::dvec3 e1 = a - p, e2 = b - p;
  e1 -= n * glm::dot(n, e1);
  e2 -= n * glm::dot(n, e2);
  const double l1 = glm::length(e1), l2 = glm::length(e2);
  if (!(l1 > 0.0) || !(l2 > 0.0)) return 0.0;
  return std::acos(std::clamp(glm::dot(e1, e2) / (l1 * l2), -1.0, 1.0));
}

}  // namespace

glm::vec3 anyTangent(const glm::vec3& n) {
  const float sign = std::copysign(1.0f, n.z);
  const float a = -1.0f / (sign + n.z), b = n.x * n.y * a;
  return glm::vec3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
}

glm::vec3 orthogonalTangent(const glm::vec3& tangent, const glm::vec3& n, bool& ok) {
  const glm::dvec3 nd(n);
  const glm::dvec3 t = glm::dvec3(tangent) - nd * glm::dot(nd, glm::dvec3(tangent));
  const double len = glm::length(t);
  ok = finite(tangent) && len > 1e-12 && std::isfinite(len);
  return ok ? glm::vec3(t / len) : anyTangent(n);
}

TangentResult generateTangents(const std::vector<glm::vec3>& positions, const std::vector<glm::vec3>& normals,
                               const std::vector<glm::vec2>& uvs, const std::vector<uint32_t>& indices) {
  const size_t n = positions.size();
  TangentResult out;
  out.tangents.assign(n, glm::vec4(0.0f));
  if (normals.size() != n || uvs.size() != n) return out;
  const std::vector<uint32_t> canonical = weldIdentical(positions, normals, uvs);
  // Per canonical vertex and orientation (0: preserving, 1: not): Σ angle · projected tangent, Σ angle.
  std::vector<glm::dvec3> sum(2 * n, glm::dvec3(0.0));
  std::vector<double> weight(2 * n, 0.0);
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    glm::dvec3 p[3];
    glm::dvec2 uv[3];
    uint32_t v[3];
    for (int k = 0; k < 3; ++k) {
      v[k] = canonical[indices[t + size_t(k)]];
      p[k] = glm::dvec3(positions[v[k]]);
      uv[k] = glm::dvec2(uvs[v[k]]);
    }
    glm::dvec3 os;
    bool preserving = true;
    if (!triangleTangent(p, uv, os, preserving)) continue;
    for (int k = 0; k < 3; ++k) {
      const glm::dvec3 nk(normals[v[k]]);
      glm::dvec3 projected = os - nk * glm::dot(nk, os);
      const double len = glm::length(projected);
      const double angle = cornerAngle(p[k], p[(k + 1) % 3], p[(k + 2) % 3], nk);
      if (!(len > 0.0) || !std::isfinite(len) || !(angle > 0.0)) continue;
      const size_t slot = 2 * size_t(v[k]) + (preserving ? 0 : 1);
      sum[slot] += projected / len * angle;
      weight[slot] += angle;
    }
  }
  for (size_t i = 0; i < n; ++i) {
    const uint32_t c = canonical[i];
    const size_t pick = weight[2 * c + 1] > weight[2 * c] ? 1 : 0;  // step 4: the larger orientation
    bool ok = false;
    const glm::vec3 t = orthogonalTangent(glm::vec3(sum[2 * c + pick]), normals[i], ok);
    if (!ok) ++out.degenerateVertices;
    out.tangents[i] = glm::vec4(t, ok && pick == 1 ? -1.0f : 1.0f);
  }
  return out;
}

}  // namespace prt
