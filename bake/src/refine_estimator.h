// What adaptive refinement measures (refine.cpp, refine_estimator.cpp): per point, which of its
// directions are blocked, and per candidate (an edge's midpoint or a triangle's centroid
// against the corners that interpolate there) the interpolation error that visibility adds,
// less its Monte Carlo noise, relative to the unoccluded transfer's norm.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/ray_scene.h"
#include "prt/bake/sampling.h"
#include "unbury.h"

namespace prt::bake::refinement {

// Where a point's estimate is taken: its position, normal and pull (liftedOrigin), and the
// points of its own surface a buried point may move towards (unbury.h).
struct Point {
  glm::vec3 position, normal, pull;
  std::array<glm::vec3, kMaxTargets> target{};
  int targets = 0;
  void addTarget(const glm::vec3& t) {
    if (size_t(targets) < kMaxTargets) target[size_t(targets++)] = t;
  }
};

// What the rays of each point found: its normal and, per direction, whether it was blocked.
struct Estimates {
  static constexpr uint32_t kNone = ~uint32_t(0);
  size_t words = 0;  // 64-bit words of blocked bits per point
  std::vector<glm::vec3> normal;
  std::vector<uint64_t> blocked;
  std::vector<uint32_t> back;  // per point: the slot of its back side (double-sided instances), or kNone
  uint32_t add() {
    normal.emplace_back(0.0f);
    blocked.resize(blocked.size() + words, 0);
    back.push_back(kNone);
    return uint32_t(normal.size() - 1);
  }
};

class Estimator {
 public:
  Estimator(const RayScene& rays, int bands, uint32_t samples, uint64_t seed, float extent);

  uint32_t samples() const { return samples_; }

  // Traces point p into slot `slot` of `out` (thread-safe for distinct slots).
  void trace(const Point& p, Estimates& out, uint32_t slot) const;

  // The score of a candidate: point pts[0] (a midpoint or centroid) against the mean of points
  // pts[1..n-1] (the corners that interpolate there); n ≤ 4.
  double score(const Estimates& est, const uint32_t* pts, int n) const;

 private:
  uint64_t validBits(size_t word, size_t words) const;
  void unoccludedError(const Estimates& est, const uint32_t* pts, int n, bool same, Frame* frame, double* eu) const;
  double meanSeenShare(const Estimates& est, const uint32_t* pts, int n) const;
  bool fewerBlocked(const Estimates& est, const uint32_t* pts, int n) const;
  void sumDifferences(const Estimates& est, const uint32_t* pts, int n, bool same, bool overBlocked, const Frame* frame,
                      double* sum, double* sum2) const;

  const RayScene& rays_;
  int bands_, n2_;
  uint32_t samples_;
  uint64_t seed_;
  float extent_, tnear_;
  std::vector<glm::vec3> local_;  // direction s about +Z, as VertexSampler makes it for every point
  double reference_;              // |t^unocc|
};

}  // namespace prt::bake::refinement
