// glTF animations: channels read and validated (targets, interpolation, key times, values),
// and the instances they move made receivers. The renderer moves receivers with them; the bake
// is static. Sampling is in animation.cpp. Part of the glTF reader (gltf_reader.h).
#include <cmath>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "animation_labels.h"
#include "gltf_reader.h"
#include "prt/animation.h"
#include "prt/error.h"

namespace prt::gltf {

using detail::nodeLabel;
using detail::pathName;

namespace {

/// The node and property a channel animates; false if it is skipped (with a warning).
bool readTarget(const Gltf& g, const tinygltf::AnimationChannel& ch, const std::string& where, AnimationChannel& out,
                std::vector<std::string>& warnings) {
  const tinygltf::Model& m = g.model;
  if (ch.target_node < 0) {
    warnings.push_back(cat(g.path, ": ", where, ": no target node, ignored"));
    return false;
  }
  if (size_t(ch.target_node) >= m.nodes.size())
    fail(g, cat(where, ": target node ", ch.target_node, " does not exist (the file has ", m.nodes.size(), ")"));
  out.node = ch.target_node;
  if (ch.target_path == "translation") {
    out.path = AnimationPath::Translation;
  } else if (ch.target_path == "rotation") {
    out.path = AnimationPath::Rotation;
  } else if (ch.target_path == "scale") {
    out.path = AnimationPath::Scale;
  } else if (ch.target_path == "weights") {
    warnings.push_back(cat(g.path, ": ", where, ": morph target weights are not supported, ignored"));
    return false;
  } else {
    fail(g, cat(where, ": unknown target path '", ch.target_path, "'"));
  }
  if (!m.nodes[size_t(out.node)].matrix.empty())
    fail(g, cat(where, ": node ", out.node, " has a matrix; glTF animates only nodes given as TRS"));
  return true;
}

Interpolation readInterpolation(const Gltf& g, const tinygltf::AnimationSampler& s, const std::string& where) {
  if (s.interpolation == "LINEAR" || s.interpolation.empty()) return Interpolation::Linear;
  if (s.interpolation == "STEP") return Interpolation::Step;
  if (s.interpolation == "CUBICSPLINE") return Interpolation::CubicSpline;
  fail(g, cat(where, ": unknown interpolation '", s.interpolation, "'"));
}

/// The sampler's input: SCALAR float key times, finite and strictly increasing.
void readKeyTimes(const Gltf& g, const tinygltf::AnimationSampler& s, const std::string& where, AnimationChannel& out) {
  const std::string inWhere = cat(where, " / input");
  const AccessorData in = openAccessor(g, s.input, inWhere);
  if (in.components != 1 || in.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
    fail(g, cat(inWhere, ": key times must be SCALAR float, accessor ", s.input, " is ",
                typeName(in.components == 1 ? TINYGLTF_TYPE_SCALAR : in.components), " of component type ",
                in.componentType));
  const size_t keys = in.count;
  const bool cubic = out.interpolation == Interpolation::CubicSpline;
  if (keys < (cubic ? 2u : 1u))
    fail(g, cat(inWhere, ": ", keys, " key times, ", cubic ? "CUBICSPLINE needs at least 2" : "expected at least 1"));
  out.times.resize(keys);
  for (size_t k = 0; k < keys; ++k) {
    out.times[k] = in.get(k, 0);
    if (!std::isfinite(out.times[k])) fail(g, cat(inWhere, ": key time ", k, " is not finite"));
    if (k > 0 && !(out.times[k] > out.times[k - 1]))
      fail(g, cat(inWhere, ": key times not strictly increasing (key ", k, " at ", out.times[k], " s after ",
                  out.times[k - 1], " s)"));
  }
}

/// The sampler's output: one value per key time (three with CUBICSPLINE's tangents), finite,
/// rotations non-zero.
void readKeyValues(const Gltf& g, const tinygltf::AnimationSampler& s, const std::string& where,
                   AnimationChannel& out) {
  const std::string outWhere = cat(where, " / output");
  const AccessorData val = openAccessor(g, s.output, outWhere);
  const size_t keys = out.times.size();
  const bool cubic = out.interpolation == Interpolation::CubicSpline;
  const bool rotation = out.path == AnimationPath::Rotation;
  const int want = rotation ? 4 : 3;
  const bool floatType = val.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT;
  // glTF allows normalized byte and short quaternions; translation and scale are float only.
  const bool normalizedRotation =
      rotation && val.normalized && val.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  if (val.components != want || !(floatType || normalizedRotation))
    fail(g, cat(outWhere, ": ", pathName(out.path), " values must be ", rotation ? "VEC4" : "VEC3",
                rotation ? " float or normalized integers" : " float", ", accessor ", s.output, " has ", val.components,
                " components of component type ", val.componentType, val.normalized ? " (normalized)" : ""));
  const size_t expected = keys * (cubic ? 3 : 1);
  if (val.count != expected)
    fail(g, cat(outWhere, ": ", val.count, " values, expected ", expected, " (", keys, " key times",
                cubic ? " × 3 for CUBICSPLINE: in-tangent, value, out-tangent" : "", ")"));
  out.values.resize(expected);
  for (size_t i = 0; i < expected; ++i) {
    glm::dvec4 v(0.0);
    for (int c = 0; c < want; ++c) v[c] = val.get(i, c);
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z) || !std::isfinite(v.w))
      fail(g, cat(outWhere, ": value ", i, " is not finite"));
    const bool isValue = !cubic || i % 3 == 1;  // tangents may be anything finite
    if (rotation && isValue && glm::length(v) == 0.0) fail(g, cat(outWhere, ": value ", i, " is a zero quaternion"));
    out.values[i] = v;
  }
}

/// Reads and validates one channel; false if it is skipped (with a warning).
bool readChannel(const Gltf& g, const tinygltf::Animation& anim, const tinygltf::AnimationChannel& ch,
                 const std::string& where, AnimationChannel& out, std::vector<std::string>& warnings) {
  if (!readTarget(g, ch, where, out, warnings)) return false;
  if (ch.sampler < 0 || size_t(ch.sampler) >= anim.samplers.size())
    fail(g, cat(where, ": sampler ", ch.sampler, " does not exist (the animation has ", anim.samplers.size(), ")"));
  const tinygltf::AnimationSampler& s = anim.samplers[size_t(ch.sampler)];
  out.interpolation = readInterpolation(g, s, where);
  readKeyTimes(g, s, where, out);
  readKeyValues(g, s, where, out);
  return true;
}

}  // namespace

void readAnimations(const Gltf& g, Scene& scene) {
  const tinygltf::Model& m = g.model;
  for (size_t a = 0; a < m.animations.size(); ++a) {
    const tinygltf::Animation& anim = m.animations[a];
    Animation out;
    out.name = anim.name;
    const std::string animWhere = cat("animation ", a, anim.name.empty() ? "" : cat(" '", anim.name, "'"));
    std::set<std::pair<int, int>> targets;
    for (size_t c = 0; c < anim.channels.size(); ++c) {
      const tinygltf::AnimationChannel& ch = anim.channels[c];
      const int node = ch.target_node;
      std::string nodeName = node >= 0 && size_t(node) < m.nodes.size() && !m.nodes[size_t(node)].name.empty()
                                 ? cat(" '", m.nodes[size_t(node)].name, "'")
                                 : std::string();
      const std::string where = cat(animWhere, " / channel ", c, " (node ", node, nodeName, " ", ch.target_path, ")");
      AnimationChannel channel;
      if (!readChannel(g, anim, ch, where, channel, scene.warnings)) continue;
      // The spec: within one animation, each node property is the target of one channel only.
      if (!targets.insert({channel.node, int(channel.path)}).second)
        fail(g, cat(where, ": a second channel of this animation targets the same node property"));
      out.channels.push_back(std::move(channel));
    }
    scene.animations.push_back(std::move(out));
  }
}

void makeAnimatedInstancesReceivers(const Gltf& g, Scene& scene, const std::vector<char>& keepStatic) {
  std::set<int> warned;
  for (MeshInstance& inst : scene.meshes) {
    if (inst.receiverOnly || !isAnimated(scene, inst.node)) continue;
    if (!keepStatic[size_t(inst.node)]) {
      inst.receiverOnly = true;
      inst.receiverReason = ReceiverReason::Animated;
    } else if (warned.insert(inst.node).second) {
      scene.warnings.push_back(cat(g.path, ": ", nodeLabel(scene, inst.node),
                                   " is animated but marked static (extras prt.receiver = false): baked in its "
                                   "rest pose, its animation is ignored"));
    }
  }
}

}  // namespace prt::gltf
