// Animation: the node hierarchy and animation channels of a glTF file, and the transforms they
// give each node at a time t. The bake is static; the renderer moves receivers with these.
#pragma once

#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace prt {

struct MeshInstance;  // prt/scene.h

/// A glTF node: its place in the hierarchy and its rest transform (what it has without
/// animation). Indices are the file's node indices (MeshInstance::node, Camera::node).
struct Node {
  std::string name;
  int parent = -1;         // -1: a root, or a node outside the default scene
  bool hasMatrix = false;  // rest transform given as a matrix (glTF forbids animating it)
  glm::dmat4 matrix{1.0};  // when hasMatrix
  glm::dvec3 translation{0.0};
  glm::dvec4 rotation{0, 0, 0, 1};  // unit quaternion (x, y, z, w), glTF's order
  glm::dvec3 scale{1.0};
};

/// Which node property a channel drives. Morph-target weights are not read.
enum class AnimationPath { Translation, Rotation, Scale };
/// glTF sampler interpolation.
enum class Interpolation { Linear, Step, CubicSpline };

/// One validated glTF animation channel with its sampler's keys.
struct AnimationChannel {
  int node = -1;
  AnimationPath path = AnimationPath::Translation;
  Interpolation interpolation = Interpolation::Linear;
  std::vector<double> times;  // seconds, >= 0, strictly increasing, at least one key
  /// One value per key (Linear, Step) or three (CubicSpline: in-tangent, value, out-tangent).
  /// xyz for translation and scale (w unused); a quaternion (x, y, z, w) for rotation.
  std::vector<glm::dvec4> values;
};

struct Animation {
  std::string name;
  std::vector<AnimationChannel> channels;
};

/// Every node of the file (index = glTF node index) and every animation; all animations play
/// together from t = 0 (docs/render.md, "Animation"). A value of its own, so that whoever only
/// moves things (the renderer) keeps this and not the whole Scene.
struct SceneAnimation {
  std::vector<Node> nodes;
  std::vector<Animation> animations;
};

/// Value of one channel at time t (seconds), per the glTF 2.0 spec: Linear (rotation by
/// shortest-path slerp), Step, CubicSpline (Hermite; tangents scaled by the key interval).
/// Clamped to the first / last key outside the key range. Rotations come back unit length.
glm::dvec4 sampleChannel(const AnimationChannel& channel, double t);
/// True if `node` or one of its ancestors is driven by an animation channel.
bool isAnimated(const SceneAnimation& animation, int node);
/// World transform of `node` at time t: every ancestor's local TRS with the animated
/// properties replaced by their sampled values, composed root first.
glm::dmat4 nodeWorldAt(const SceneAnimation& animation, int node, double t);
/// Matrix that takes an instance's stored (rest pose, world space) positions to where its node
/// puts them at time t: nodeWorldAt(t) · world⁻¹. Exactly identity when the node is not
/// animated.
glm::dmat4 instanceMotion(const SceneAnimation& animation, const MeshInstance& mesh, double t);
/// Last key time over every channel (0 without animations).
double animationDuration(const SceneAnimation& animation);

}  // namespace prt
