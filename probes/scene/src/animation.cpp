// Animation sampling (glTF 2.0 spec, Appendix C "Animation Sampler Interpolation Modes"): node
// transforms at a time t, and why each receiver is one.
#include "prt/animation.h"

#include <algorithm>
#include <cmath>
#include <set>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include "animation_labels.h"
#include "prt/error.h"
#include "prt/scene.h"

namespace prt {

namespace detail {

const char* pathName(AnimationPath p) {
  switch (p) {
    case AnimationPath::Translation:
      return "translation";
    case AnimationPath::Rotation:
      return "rotation";
    case AnimationPath::Scale:
      return "scale";
  }
  return "?";
}

/// "node 3 'Box'" (the name only where the node has one).
std::string nodeLabel(const SceneAnimation& animation, int node) {
  const bool named = node >= 0 && size_t(node) < animation.nodes.size() && !animation.nodes[size_t(node)].name.empty();
  return cat("node ", node, named ? cat(" '", animation.nodes[size_t(node)].name, "'") : std::string());
}

}  // namespace detail

using detail::nodeLabel;
using detail::pathName;

namespace {

glm::dvec4 unitQuaternion(const glm::dvec4& q) {
  const double len = glm::length(q);
  return len > 0.0 ? q / len : glm::dvec4(0, 0, 0, 1);
}

/// The spec's slerp: along the shorter arc (q and −q are one rotation), linear where the two
/// are nearly parallel (sin of the angle → 0).
glm::dvec4 slerp(glm::dvec4 a, glm::dvec4 b, double s) {
  a = unitQuaternion(a);
  b = unitQuaternion(b);
  double d = glm::dot(a, b);
  if (d < 0.0) {
    b = -b;
    d = -d;
  }
  if (d > 1.0 - 1e-12) return unitQuaternion(a + s * (b - a));
  const double angle = std::acos(d), sinAngle = std::sin(angle);
  return (std::sin((1.0 - s) * angle) * a + std::sin(s * angle) * b) / sinAngle;
}

glm::dmat4 trs(const glm::dvec3& t, const glm::dvec4& q, const glm::dvec3& s) {
  const glm::dquat r(q.w, q.x, q.y, q.z);  // glm: (w, x, y, z); glTF: (x, y, z, w)
  return glm::translate(glm::dmat4(1.0), t) * glm::mat4_cast(r) * glm::scale(glm::dmat4(1.0), s);
}

glm::dmat4 nodeLocalAt(const SceneAnimation& animation, int node, double t) {
  const Node& n = animation.nodes[size_t(node)];
  if (n.hasMatrix) return n.matrix;  // never animated (refused at load)
  glm::dvec3 translation = n.translation, scale = n.scale;
  glm::dvec4 rotation = n.rotation;
  for (const Animation& a : animation.animations)
    for (const AnimationChannel& c : a.channels) {
      if (c.node != node) continue;
      const glm::dvec4 v = sampleChannel(c, t);
      if (c.path == AnimationPath::Translation) translation = glm::dvec3(v);
      if (c.path == AnimationPath::Rotation) rotation = v;
      if (c.path == AnimationPath::Scale) scale = glm::dvec3(v);
    }
  return trs(translation, rotation, scale);
}

bool nodeDriven(const SceneAnimation& animation, int node) {
  for (const Animation& a : animation.animations)
    for (const AnimationChannel& c : a.channels)
      if (c.node == node) return true;
  return false;
}

}  // namespace

glm::dvec4 sampleChannel(const AnimationChannel& ch, double t) {
  PRT_CHECK(!ch.times.empty());
  const bool cubic = ch.interpolation == Interpolation::CubicSpline;
  const bool rotation = ch.path == AnimationPath::Rotation;
  PRT_CHECK_EQ(ch.values.size(), ch.times.size() * (cubic ? 3 : 1));
  auto value = [&](size_t k) { return cubic ? ch.values[3 * k + 1] : ch.values[k]; };
  auto finish = [&](const glm::dvec4& v) { return rotation ? unitQuaternion(v) : v; };
  const size_t n = ch.times.size();
  if (!(t > ch.times.front())) return finish(value(0));  // before the first key (and NaN)
  if (t >= ch.times.back()) return finish(value(n - 1));
  // times[k] <= t < times[k + 1]
  const size_t k = size_t(std::upper_bound(ch.times.begin(), ch.times.end(), t) - ch.times.begin()) - 1;
  const double td = ch.times[k + 1] - ch.times[k];
  const double s = (t - ch.times[k]) / td;
  switch (ch.interpolation) {
    case Interpolation::Step:
      return finish(value(k));
    case Interpolation::Linear:
      return rotation ? slerp(value(k), value(k + 1), s) : value(k) + s * (value(k + 1) - value(k));
    case Interpolation::CubicSpline: {
      // Hermite spline with the out-tangent b_k of key k and the in-tangent a_{k+1} of key k+1,
      // both scaled by the interval t_d:
      // p(s) = (2s³−3s²+1) v_k + t_d (s³−2s²+s) b_k + (−2s³+3s²) v_{k+1} + t_d (s³−s²) a_{k+1}
      const double s2 = s * s, s3 = s2 * s;
      const glm::dvec4 p = (2 * s3 - 3 * s2 + 1) * value(k) + td * (s3 - 2 * s2 + s) * ch.values[3 * k + 2] +
                           (-2 * s3 + 3 * s2) * value(k + 1) + td * (s3 - s2) * ch.values[3 * (k + 1)];
      return finish(p);
    }
  }
  return finish(value(k));
}

bool isAnimated(const SceneAnimation& animation, int node) {
  // Bounded walk: a malformed hierarchy outside the default scene must not loop forever.
  for (size_t steps = 0; node >= 0 && size_t(node) < animation.nodes.size() && steps <= animation.nodes.size();
       ++steps) {
    if (nodeDriven(animation, node)) return true;
    node = animation.nodes[size_t(node)].parent;
  }
  return false;
}

glm::dmat4 nodeWorldAt(const SceneAnimation& animation, int node, double t) {
  PRT_CHECK(node >= 0 && size_t(node) < animation.nodes.size());
  glm::dmat4 world = nodeLocalAt(animation, node, t);
  int p = animation.nodes[size_t(node)].parent;
  for (size_t steps = 0; p >= 0 && steps <= animation.nodes.size(); ++steps) {
    world = nodeLocalAt(animation, p, t) * world;
    p = animation.nodes[size_t(p)].parent;
  }
  return world;
}

glm::dmat4 instanceMotion(const SceneAnimation& animation, const MeshInstance& mesh, double t) {
  if (!isAnimated(animation, mesh.node)) return glm::dmat4(1.0);
  return nodeWorldAt(animation, mesh.node, t) * glm::inverse(mesh.world);
}

double animationDuration(const SceneAnimation& animation) {
  double end = 0.0;
  for (const Animation& a : animation.animations)
    for (const AnimationChannel& c : a.channels) end = std::max(end, c.times.back());
  return end;
}

namespace {

/// "translation, scale of node 2 'Arm'": the properties that animations drive on `node` and
/// its ancestors, each once.
std::string drivenProperties(const SceneAnimation& animation, int node) {
  std::vector<std::string> parts;
  for (int n = node, steps = 0; n >= 0 && size_t(n) < animation.nodes.size() && size_t(steps) <= animation.nodes.size();
       n = animation.nodes[size_t(n)].parent, ++steps)
    for (const Animation& a : animation.animations)
      for (const AnimationChannel& c : a.channels) {
        if (c.node != n) continue;
        std::string part =
            n == node ? std::string(pathName(c.path)) : cat(pathName(c.path), " of ", nodeLabel(animation, n));
        if (std::find(parts.begin(), parts.end(), part) == parts.end()) parts.push_back(std::move(part));
      }
  std::string out;
  for (const std::string& p : parts) out += (out.empty() ? "" : ", ") + p;
  return out;
}

}  // namespace

std::vector<std::string> describeReceivers(const Scene& scene, const std::string& receiverOption) {
  std::vector<std::string> lines;
  std::set<int> seen;
  for (const MeshInstance& m : scene.meshes) {
    if (!m.receiverOnly || (m.node >= 0 && !seen.insert(m.node).second)) continue;
    std::string why = m.receiverReason == ReceiverReason::Option   ? cat("named in ", receiverOption)
                      : m.receiverReason == ReceiverReason::Extras ? "extras.prt.receiver"
                                                                   : "";
    if (isAnimated(scene, m.node))
      why += cat(why.empty() ? "" : ", ", "animated (", drivenProperties(scene, m.node), ")");
    if (why.empty()) why = "receiverOnly set by the caller";
    lines.push_back(cat(m.node >= 0 ? nodeLabel(scene, m.node) : cat("'", m.name, "'"), ": ", why));
  }
  return lines;
}

}  // namespace prt
