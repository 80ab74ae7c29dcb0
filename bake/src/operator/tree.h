// The operator's nodes (prt/bounce_operator.h): surface clusters found by splitting the vertex
// sides at the median of their widest spread of position and normal, and sky bins split in
// halves, each tree's leaves in depth-first order so that every node covers a range of them.
// Private to the operator's build (build.cpp).
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/surface_layout.h"
#include "prt/bounce_operator.h"
#include "prt/scene.h"

namespace prt::bake::op {

/// A vertex side as clustering sees it.
struct SidePoint {
  glm::vec3 position, normal;
  float area = 0.0f;
  glm::vec3 albedo{0.0f};
};

/// The tree of an operator under construction, with what the build needs beyond what is stored.
struct Tree {
  std::vector<uint32_t> leafLo, leafHi;  // per node: the leaves below it, [lo, hi)
  std::vector<glm::vec3> center;         // per node: area-weighted centroid (sky: unit mean direction)
  std::vector<float> radius;             // per node: bounding radius (sky: angular radius, radians)
  std::vector<glm::vec3> axis;           // per surface node: the mean normal of its sides
  std::vector<float> cone;               // per node: 1 − cos of its normals' largest angle to `axis` (sky: 0)
  std::vector<uint32_t> clusterOf;       // per vertex side: its cluster (leaf)
  std::vector<uint32_t> skyLeafOfBin;    // per sky bin: its leaf
};

/// Per vertex side of the bake's numbering (makeLayout): a third of the area of each triangle
/// around its vertex (the same for both sides).
std::vector<float> sideAreas(const Scene& scene, const Layout& lay);

/// Fills op's clusters, albedo, members (the first samplePoints of each spread over it), sky
/// bins, leaf weights, children and roots, and returns the build's view of the tree. Needs
/// op.clusterSize, skyWidth, skyHeight, samplePoints and vertexSides set.
Tree buildTree(BounceOperator& op, const std::vector<SidePoint>& sides);

/// What merging a row's entries below node n risks, per unit of their weight, seen from x: its
/// angular size (surface: radius over distance, at most 1; sky: its angular radius), plus how
/// far its normals spread (a node holding both sides of a wall, or walls facing apart, holds
/// light the row may not see).
inline float mergeRisk(const Tree& t, uint32_t n, bool sky, const glm::vec3& x) {
  if (sky) return t.radius[n];
  const float d = glm::length(t.center[n] - x);
  return (d > t.radius[n] ? t.radius[n] / d : 1.0f) + t.cone[n];
}

}  // namespace prt::bake::op
