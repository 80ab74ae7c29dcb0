// Sample points moved out of the geometry that buries them (docs/bake.md, "Buried vertices").
//
// Real levels interpenetrate: a house stands sunk into the terrain, a road's embankment runs
// into the grass, a map's brushes overlap. A vertex below such a surface sees its underside and
// little else, and the dark it measures is interpolated over every triangle it holds, up to the
// visible part: a dark band along the contact line that the eye (and a path tracer, which shades
// each visible point) never sees. Lightmappers test their texels for back faces and move or
// discard the buried ones (Unity's backface tolerance, Unreal's Lightmass, Bakery's sample
// adjustment); prt moves a buried vertex's ray origin along its own triangles to just past the
// surface that buries it, so the vertex stands for the nearest visible point of its surface.
//
// The rule, a function of the geometry alone (the same for the bake, refinement, `prt relight`
// and `prt render`, any thread count or rank):
//   1. The point is *buried* when more than kBuriedRays of kProbeRays fixed cosine-weighted
//      directions about its normal first hit a back face (a triangle seen from behind, one- or
//      double-sided alike: geometry's winding says where its outside is).
//   2. Then, towards each of its targets (the other corners of its triangles, then their
//      centroids), a ray runs from the lifted origin parallel to the surface; one whose first hit
//      is a back face short of the target crosses the burying surface, and the point just past
//      it (by the origin's lift) is a candidate.
//   3. The nearest candidate that is not buried is the origin; with none, the origin stays.
// A point under a table is buried by rule 1 but no ray along the floor crosses the table, so it
// stays; a wall's foot under the terrain moves up its wall to just above the grass line.
// Front sides only: the back side of a double-sided surface faces against its winding, so back
// faces are what it sees inside any closed double-sided model, and it keeps its origin.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/ray_scene.h"

namespace prt::bake {

// Directions of the buried test, and how many of them may see back faces.
constexpr int kProbeRays = 16;
constexpr int kBuriedRays = 4;

/// At most this many targets are tried per point.
constexpr size_t kMaxTargets = 12;

/// The targets of each vertex of one mesh: the other corners of its triangles (each once), then
/// the triangles' centroids, at most kMaxTargets (by index: a vertex split at a seam has the
/// triangles of its own index).
class FanTargets {
 public:
  FanTargets(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& indices);
  std::span<const glm::vec3> of(size_t v) const { return {target_.data() + start_[v], target_.data() + start_[v + 1]}; }

 private:
  std::vector<uint32_t> start_;
  std::vector<glm::vec3> target_;
};

/// How many of the kProbeRays directions about n from `origin` first hit a back face.
int backFaceRays(const RayScene& rays, const glm::vec3& origin, const glm::vec3& n, float tnear);

/// The ray origin of a point at `p` with unit normal `n`, lifted origin `origin` (liftedOrigin)
/// and targets on its own surface (FanTargets): `origin`, or where the point is buried, the
/// nearest point towards a target just past the surface that buries it.
glm::vec3 unburiedOrigin(const RayScene& rays, const glm::vec3& p, const glm::vec3& n, const glm::vec3& origin,
                         std::span<const glm::vec3> targets, float extent);

}  // namespace prt::bake
