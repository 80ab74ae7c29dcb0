// What the operator's rows are cut against (build.cpp): a set of training lights whose values
// are known at every node, so that a row's error when it merges a node's leaves into one entry
// is measured, not guessed; and the transfer shares by which a vertex side without a row of its
// own is lit from its cluster's light (evaluate.cpp uses the same). Private to the operator.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/ray_scene.h"
#include "prt/bake/surface_layout.h"
#include "prt/bounce_operator.h"
#include "prt/scene.h"
#include "prt/sh.h"
#include "tree.h"

namespace prt::bake::op {

/// t⁰ · l and (t − t⁰) · l at vertex side v: its direct and bounced transfer of SH light l (0
/// where the instance has no direct part).
glm::vec3 shDirect(const Scene& scene, const Layout& lay, size_t v, const sh::ShRgb& l);
glm::vec3 shBounced(const Scene& scene, const Layout& lay, size_t v, const sh::ShRgb& l);

/// How much more of its cluster's bounced light, and of its cluster's sky detail, a vertex side
/// gets, by its own transfer: coefficient 0 of t − t⁰ (how much of its hemisphere other surfaces
/// fill) and of t⁰ (its open sky), each over the cluster's area-weighted mean; 1 without
/// transfer. Per vertex side.
struct TransferShares {
  std::vector<float> bounce, sky;
};
TransferShares transferShares(const Scene& scene, const Layout& lay, const BounceOperator& op,
                              const std::vector<float>& area);

/// Per vertex side: its place (s, t) in its cluster's plane (BounceOperator::clusterGradients):
/// axes two tangents of the members' mean normal, origin their area-weighted centroid (the plain
/// mean without area), per unit of the largest distance of a member from it; (0, 0) in a cluster
/// without extent.
std::vector<glm::vec2> clusterCoordinates(const Scene& scene, const Layout& lay, const BounceOperator& op,
                                          const std::vector<float>& area);

/// The training lights: kTrainingSuns suns of unit irradiance from directions spread over the
/// sphere, each with a bright disk in the sky, and kTrainingLamps point lights inside the scene
/// (trainSides). What goes through the operator is what the SH transfer does not carry
/// (docs/lights.md, "The bounce operator"), so a node's value is that residual: on a surface node
/// the radiosity ρ (E⁰ − t⁰ · sun's SH), E⁰ the sun's shadowed light (one shadow ray per vertex
/// side), or a lamp's ρ E⁰ (a lamp has no SH part); on a sky node the disk's π (L − L̃), L̃ its
/// band-limited part (0 for a lamp). Inner nodes hold the weighted mean of their leaves, as at a
/// light change.
constexpr int kTrainingSuns = 24, kTrainingLamps = 16;
constexpr int kTrainingLights = kTrainingSuns + kTrainingLamps;

/// Per vertex side, under the training suns.
struct SideTraining {
  std::vector<float> residual;  // vertex sides × kTrainingLights: E⁰ − t⁰ · sun (luminance)
  /// The mean light (luminance) the side receives under the training lights, direct, bounced
  /// and a dim uniform sky: what a row's error is relative to.
  std::vector<float> scale;
  const float* of(size_t v) const { return &residual[v * kTrainingLights]; }
};
SideTraining trainSides(const Scene& scene, const Layout& lay, const RayScene& rays,
                        const std::vector<glm::vec3>& origins);

/// Per node of a built tree.
struct Training {
  static constexpr int kLights = kTrainingLights;
  std::vector<float> value;  // nodes × kLights, node-major
  const float* of(uint32_t node) const { return &value[size_t(node) * kLights]; }
};
Training trainNodes(const Scene& scene, const BounceOperator& op, const SideTraining& sides,
                    const std::vector<float>& area);

}  // namespace prt::bake::op
