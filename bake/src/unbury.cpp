// Sample points moved out of the geometry that buries them (unbury.h).
#include "unbury.h"

#include <algorithm>
#include <array>
#include <limits>

#include "prt/bake/sampling.h"
#include "vertex_rays.h"

namespace prt::bake {

namespace {

// The buried test's directions about +Z: the first kProbeRays points of the unscrambled Sobol
// sequence, cosine-weighted, the same for every point.
const std::array<glm::vec3, kProbeRays>& probeDirections() {
  static const std::array<glm::vec3, kProbeRays> dirs = [] {
    std::array<glm::vec3, kProbeRays> d{};
    for (uint32_t j = 0; j < uint32_t(kProbeRays); ++j) d[j] = sampleCosineHemisphere({sobol0(j, 0), sobol1(j, 0)});
    return d;
  }();
  return dirs;
}

}  // namespace

FanTargets::FanTargets(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& indices)
    : start_(positions.size() + 1, 0) {
  // Per vertex, its triangles (CSR), then its targets in that order.
  std::vector<uint32_t> first(positions.size() + 1, 0), tris(indices.size());
  for (size_t i = 0; i + 2 < indices.size(); i += 3)
    for (int j = 0; j < 3; ++j) ++first[indices[i + j] + 1];
  for (size_t v = 0; v < positions.size(); ++v) first[v + 1] += first[v];
  std::vector<uint32_t> at(first.begin(), first.end() - 1);
  for (size_t i = 0; i + 2 < indices.size(); i += 3)
    for (int j = 0; j < 3; ++j) tris[at[indices[i + j]]++] = uint32_t(i);
  std::vector<uint32_t> corners;
  for (size_t v = 0; v < positions.size(); ++v) {
    corners.clear();
    for (uint32_t k = first[v]; k < first[v + 1]; ++k)
      for (int j = 0; j < 3; ++j)
        if (const uint32_t c = indices[tris[k] + j]; c != v) corners.push_back(c);
    std::sort(corners.begin(), corners.end());
    corners.erase(std::unique(corners.begin(), corners.end()), corners.end());
    for (size_t k = 0; k < corners.size() && target_.size() - start_[v] < kMaxTargets; ++k)
      target_.push_back(positions[corners[k]]);
    for (uint32_t k = first[v]; k < first[v + 1] && target_.size() - start_[v] < kMaxTargets; ++k) {
      const uint32_t* ix = &indices[tris[k]];
      target_.push_back((positions[ix[0]] + positions[ix[1]] + positions[ix[2]]) / 3.0f);
    }
    start_[v + 1] = uint32_t(target_.size());
  }
}

int backFaceRays(const RayScene& rays, const glm::vec3& origin, const glm::vec3& n, float tnear) {
  const Frame frame = Frame::fromNormal(n);
  alignas(64) std::array<Ray, kProbeRays> batch;
  const auto& dirs = probeDirections();
  for (int j = 0; j < kProbeRays; ++j)
    batch[j].start(origin, frame.toWorld(dirs[j]), tnear, std::numeric_limits<float>::infinity());
  rays.intersect(batch.data(), batch.size());
  int back = 0;
  for (const Ray& r : batch) back += r.hit() && r.backface();
  return back;
}

glm::vec3 unburiedOrigin(const RayScene& rays, const glm::vec3& p, const glm::vec3& n, const glm::vec3& origin,
                         std::span<const glm::vec3> targets, float extent) {
  const float tnear = tnearFor(extent), lift = liftFor(extent);
  if (targets.empty() || backFaceRays(rays, origin, n, tnear) <= kBuriedRays) return origin;
  // Where each target's ray crosses a back face, nearest first.
  std::array<std::pair<float, glm::vec3>, kMaxTargets> candidates;
  size_t count = 0;
  for (size_t i = 0; i < std::min(targets.size(), kMaxTargets); ++i) {
    const glm::vec3 d = targets[i] - p;
    const float length = glm::length(d);
    if (!(length > 2.0f * lift)) continue;
    Ray ray;
    ray.start(origin, d / length, tnear, length);
    rays.intersect(&ray, 1);
    if (!ray.hit() || !ray.backface() || ray.tfar + lift >= length) continue;
    candidates[count++] = {ray.tfar + lift, origin + ray.dir * (ray.tfar + lift)};
  }
  std::sort(candidates.begin(), candidates.begin() + ptrdiff_t(count),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  for (size_t i = 0; i < count; ++i)
    if (backFaceRays(rays, candidates[i].second, n, tnear) <= kBuriedRays) return candidates[i].second;
  return origin;
}

}  // namespace prt::bake
