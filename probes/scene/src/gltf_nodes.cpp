// glTF nodes: the hierarchy of the default scene (world transforms, receiver and static
// marks), the instances its nodes place, their cameras and KHR_lights_punctual lights, and the
// rest pose of every node for animation. Part of the glTF reader (gltf_reader.h).
#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "gltf_reader.h"
#include "prt/error.h"
#include "prt/tangents.h"

namespace prt::gltf {

namespace {

// A limit on hostile input (docs/robustness.md): the traversal recurses once per level.
constexpr int kMaxNodeDepth = 1000;

glm::dmat4 localTransform(const Gltf& g, int index) {
  const tinygltf::Node& n = g.model.nodes[size_t(index)];
  auto checkSize = [&](const std::vector<double>& v, size_t expected, const char* what) {
    if (!v.empty() && v.size() != expected)
      fail(g, cat("node ", index, ": ", what, " has ", v.size(), " values, expected ", expected));
    for (double x : v)
      if (!std::isfinite(x)) fail(g, cat("node ", index, ": ", what, " is not finite"));
  };
  checkSize(n.matrix, 16, "matrix");
  checkSize(n.translation, 3, "translation");
  checkSize(n.rotation, 4, "rotation");
  checkSize(n.scale, 3, "scale");
  if (!n.matrix.empty()) return glm::make_mat4(n.matrix.data());  // both column-major
  glm::dmat4 t(1.0), r(1.0), s(1.0);
  if (!n.translation.empty()) t = glm::translate(glm::dmat4(1.0), glm::make_vec3(n.translation.data()));
  if (!n.rotation.empty()) {
    glm::dquat q(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);  // glTF is x,y,z,w
    double len = glm::length(q);
    if (len == 0.0) fail(g, cat("node ", index, ": rotation is a zero quaternion"));
    r = glm::mat4_cast(q / len);
  }
  if (!n.scale.empty()) s = glm::scale(glm::dmat4(1.0), glm::make_vec3(n.scale.data()));
  return t * r * s;
}

struct Traversal {
  const Gltf& g;
  const NodeMarks& marks;
  std::vector<char> visited, onPath;
  std::vector<NodeVisit> out;

  void visit(int node, const NodeVisit& parent, int depth) {
    if (node < 0 || size_t(node) >= g.model.nodes.size()) fail(g, cat("node ", node, " does not exist"));
    if (onPath[size_t(node)]) fail(g, cat("node ", node, ": the node hierarchy has a cycle"));
    if (visited[size_t(node)]) fail(g, cat("node ", node, " is reached twice (glTF nodes form a tree)"));
    if (depth > kMaxNodeDepth) fail(g, cat("node ", node, ": node hierarchy deeper than ", kMaxNodeDepth, " levels"));
    visited[size_t(node)] = onPath[size_t(node)] = 1;
    const tinygltf::Node& n = g.model.nodes[size_t(node)];
    NodeVisit v{node, parent.world * localTransform(g, node),
                parent.receiver != ReceiverReason::None ? parent.receiver : marks.receiver[size_t(node)],
                parent.keepStatic || marks.keepStatic[size_t(node)] != 0};
    out.push_back(v);
    for (int child : n.children) visit(child, v, depth + 1);
    onPath[size_t(node)] = 0;
  }
};

std::vector<int> rootNodes(const Gltf& g) {
  const tinygltf::Model& m = g.model;
  if (!m.scenes.empty()) {
    int s = m.defaultScene >= 0 ? m.defaultScene : 0;
    if (size_t(s) >= m.scenes.size()) fail(g, cat("default scene ", s, " does not exist"));
    return m.scenes[size_t(s)].nodes;
  }
  std::vector<char> isChild(m.nodes.size(), 0);
  for (const tinygltf::Node& n : m.nodes)
    for (int c : n.children)
      if (c >= 0 && size_t(c) < m.nodes.size()) isChild[size_t(c)] = 1;
  std::vector<int> roots;
  for (size_t i = 0; i < m.nodes.size(); ++i)
    if (!isChild[i]) roots.push_back(int(i));
  return roots;
}

/// extras {"prt": {"receiver": true | false}}: true or false when given, empty otherwise.
std::optional<bool> extrasReceiver(const tinygltf::Node& n) {
  if (!n.extras.IsObject() || !n.extras.Has("prt")) return std::nullopt;
  const tinygltf::Value& prt = n.extras.Get("prt");
  if (!prt.IsObject() || !prt.Has("receiver")) return std::nullopt;
  const tinygltf::Value& r = prt.Get("receiver");
  if (!r.IsBool()) return std::nullopt;
  return r.Get<bool>();
}

}  // namespace

NodeMarks nodeMarks(const Gltf& g, const LoadOptions& options) {
  const auto& nodes = g.model.nodes;
  NodeMarks marks{std::vector<ReceiverReason>(nodes.size(), ReceiverReason::None), std::vector<char>(nodes.size(), 0)};
  for (size_t i = 0; i < nodes.size(); ++i) {
    const std::optional<bool> r = extrasReceiver(nodes[i]);
    if (r && *r) marks.receiver[i] = ReceiverReason::Extras;
    marks.keepStatic[i] = r && !*r;
  }
  for (const std::string& entry : options.receiverNodes) {
    bool found = false;
    for (size_t i = 0; i < nodes.size(); ++i)
      if (nodes[i].name == entry) {
        marks.receiver[i] = ReceiverReason::Option;
        found = true;
      }
    bool numeric = allDigits(entry) && entry.size() < 10;
    if (numeric && size_t(std::stoul(entry)) < nodes.size()) {
      marks.receiver[std::stoul(entry)] = ReceiverReason::Option;
      found = true;
    }
    if (!found) fail(g, cat("no node named '", entry, "'"));
  }
  return marks;
}

std::vector<NodeVisit> visitDefaultScene(const Gltf& g, const NodeMarks& marks) {
  Traversal traversal{
      g, marks, std::vector<char>(g.model.nodes.size(), 0), std::vector<char>(g.model.nodes.size(), 0), {}};
  for (int root : rootNodes(g)) traversal.visit(root, NodeVisit{}, 0);
  return std::move(traversal.out);
}

namespace {

/// The primitive's tangents in world space: xyz through the node's linear part (a tangent is a
/// direction along the surface), made orthogonal to the world normal and unit; w flipped by a
/// mirroring transform, which turns n × t against the mapped bitangent.
void setTangents(MeshInstance& inst, const PrimitiveData& p, const glm::dmat3& linear) {
  if (p.tangents.size() != inst.normals.size()) return;
  const double flip = glm::determinant(linear) < 0.0 ? -1.0 : 1.0;
  inst.tangents.resize(p.tangents.size());
  for (size_t v = 0; v < p.tangents.size(); ++v) {
    bool ok = false;
    const glm::vec3 t =
        orthogonalTangent(glm::vec3(linear * glm::dvec3(glm::vec3(p.tangents[v]))), inst.normals[v], ok);
    inst.tangents[v] = glm::vec4(t, float((p.tangents[v].w < 0.0f ? -1.0 : 1.0) * flip));
  }
}

}  // namespace

MeshInstance makeInstance(const Gltf& g, const NodeVisit& visit, int meshIndex, int primIndex, const PrimitiveData& p,
                          std::vector<std::string>& warnings) {
  const tinygltf::Node& node = g.model.nodes[size_t(visit.node)];
  const tinygltf::Mesh& mesh = g.model.meshes[size_t(meshIndex)];
  MeshInstance inst;
  inst.name = cat(node.name.empty() ? cat("node ", visit.node) : node.name, "/",
                  mesh.name.empty() ? cat("mesh ", meshIndex) : mesh.name, "/primitive ", primIndex);
  inst.node = visit.node;
  inst.mesh = meshIndex;
  inst.primitive = primIndex;
  inst.world = visit.world;
  inst.material = p.material;
  inst.receiverOnly = visit.receiver != ReceiverReason::None;
  inst.receiverReason = visit.receiver;
  inst.positions.resize(p.positions.size());
  for (size_t v = 0; v < p.positions.size(); ++v) {
    glm::dvec4 w = visit.world * glm::dvec4(glm::dvec3(p.positions[v]), 1.0);
    inst.positions[v] = glm::vec3(w);
    if (!std::isfinite(inst.positions[v].x) || !std::isfinite(inst.positions[v].y) ||
        !std::isfinite(inst.positions[v].z))
      fail(g, cat("node ", visit.node, " / ", primitiveWhere(meshIndex, primIndex), " / POSITION: vertex ", v,
                  " is not finite after the node transform"));
  }
  inst.indices = p.indices;
  glm::dmat3 linear(visit.world);
  // A mirroring transform turns counter-clockwise triangles clockwise; swapping two corners
  // keeps them front-facing (the glTF spec asks renderers to do the same).
  if (glm::determinant(linear) < 0.0)
    for (size_t t = 0; t < inst.triangleCount(); ++t) std::swap(inst.indices[3 * t + 1], inst.indices[3 * t + 2]);
  if (size_t repaired = setNormals(inst, p, linear))
    warnings.push_back(cat(g.path, ": node ", visit.node, " / ", primitiveWhere(meshIndex, primIndex), ": ", repaired,
                           " zero or non-finite normals replaced by face normals"));
  inst.texcoords = p.texcoords;
  inst.moreTexcoords = p.moreTexcoords;
  setTangents(inst, p, linear);
  inst.colors = p.colors;
  inst.fileVertex = p.fileVertex;
  inst.transfer = p.transfer;
  inst.transferBack = p.transferBack;
  inst.transferDirect = p.transferDirect;
  inst.transferDirectBack = p.transferDirectBack;
  return inst;
}

Camera readCamera(const Gltf& g, const NodeVisit& v) {
  const tinygltf::Node& n = g.model.nodes[size_t(v.node)];
  if (size_t(n.camera) >= g.model.cameras.size())
    fail(g, cat("node ", v.node, ": camera ", n.camera, " does not exist"));
  const tinygltf::Camera& src = g.model.cameras[size_t(n.camera)];
  Camera c;
  c.name = !src.name.empty() ? src.name : n.name;
  c.node = v.node;
  c.world = v.world;
  c.perspective = src.type != "orthographic";
  if (c.perspective) {
    c.yfov = src.perspective.yfov;
    c.aspectRatio = src.perspective.aspectRatio;
    c.znear = src.perspective.znear;
    c.zfar = src.perspective.zfar;
  } else {
    c.xmag = src.orthographic.xmag;
    c.ymag = src.orthographic.ymag;
    c.znear = src.orthographic.znear;
    c.zfar = src.orthographic.zfar;
  }
  for (double x : {c.yfov, c.aspectRatio, c.znear, c.zfar, c.xmag, c.ymag})
    if (!std::isfinite(x)) fail(g, cat("camera ", n.camera, ": a parameter is not finite"));
  return c;
}

// KHR_lights_punctual's ranges: colour and intensity finite and >= 0, range >= 0 (0: none
// given), 0 <= innerConeAngle < outerConeAngle <= π/2. `what` names the light.
void checkLight(const Gltf& g, const PunctualLight& l, const std::string& what, bool spot) {
  auto field = [&](const char* name, float x, bool ok, const char* range) {
    if (!std::isfinite(x)) fail(g, cat(what, ": ", name, ": not a finite number"));
    if (!ok) fail(g, cat(what, ": ", name, " ", x, ": ", range));
  };
  for (int c = 0; c < 3; ++c) field("color", l.color[c], l.color[c] >= 0.0f, "must be >= 0");
  field("intensity", l.intensity, l.intensity >= 0.0f, "must be >= 0");
  field("range", l.range, l.range >= 0.0f, "must be > 0 (or absent: infinite)");
  if (!spot) return;
  field("spot.innerConeAngle", l.innerConeAngle, l.innerConeAngle >= 0.0f, "must be >= 0");
  field("spot.outerConeAngle", l.outerConeAngle, l.outerConeAngle > 0.0f && l.outerConeAngle <= 1.5707964f,
        "must be in (0, π/2]");
  if (!(l.innerConeAngle < l.outerConeAngle))
    fail(g, cat(what, ": spot.innerConeAngle ", l.innerConeAngle, ": the inner cone must be inside the outer cone (",
                l.outerConeAngle, ")"));
}

std::optional<PunctualLight> readLight(const Gltf& g, const NodeVisit& v, std::vector<std::string>& warnings) {
  const tinygltf::Node& n = g.model.nodes[size_t(v.node)];
  auto ext = n.extensions.find(kLights);
  if (ext == n.extensions.end() || !ext->second.IsObject() || !ext->second.Has("light")) return std::nullopt;
  const tinygltf::Value& index = ext->second.Get("light");
  if (!index.IsNumber() || index.GetNumberAsInt() < 0 || size_t(index.GetNumberAsInt()) >= g.model.lights.size())
    fail(g, cat("node ", v.node, ": ", kLights, " light does not exist"));
  const tinygltf::Light& src = g.model.lights[size_t(index.GetNumberAsInt())];
  PunctualLight l;
  if (src.type == "directional")
    l.type = PunctualLight::Type::Directional;
  else if (src.type == "point")
    l.type = PunctualLight::Type::Point;
  else if (src.type == "spot")
    l.type = PunctualLight::Type::Spot;
  else {
    warnings.push_back(cat(g.path, ": node ", v.node, ": skipping light of unknown type '", src.type, "'"));
    return std::nullopt;
  }
  l.name = !src.name.empty() ? src.name : n.name;
  l.node = v.node;
  if (src.color.size() == 3) l.color = glm::vec3(src.color[0], src.color[1], src.color[2]);
  l.intensity = static_cast<float>(src.intensity);
  l.range = static_cast<float>(src.range);
  l.position = glm::vec3(v.world * glm::dvec4(0, 0, 0, 1));
  l.direction = unitOr(glm::dmat3(v.world) * glm::dvec3(0, 0, -1), glm::vec3(0, 0, -1));
  l.innerConeAngle = static_cast<float>(src.spot.innerConeAngle);
  l.outerConeAngle = static_cast<float>(src.spot.outerConeAngle);
  checkLight(g, l, cat("light ", index.GetNumberAsInt(), " '", printable(l.name), "'"), src.type == "spot");
  return l;
}

/// Every node of the file with its parent and rest TRS (or matrix). Values were validated by
/// localTransform for the nodes of the default scene; others keep identity parts where a
/// property is malformed (they place nothing).
void readNodes(const Gltf& g, Scene& scene) {
  const auto& nodes = g.model.nodes;
  scene.nodes.assign(nodes.size(), Node{});
  for (size_t i = 0; i < nodes.size(); ++i) {
    const tinygltf::Node& n = nodes[i];
    Node& out = scene.nodes[i];
    out.name = n.name;
    if (n.matrix.size() == 16) {
      out.hasMatrix = true;
      out.matrix = glm::make_mat4(n.matrix.data());
    }
    if (n.translation.size() == 3) out.translation = glm::make_vec3(n.translation.data());
    if (n.rotation.size() == 4) {
      const glm::dvec4 q = glm::make_vec4(n.rotation.data());
      if (glm::length(q) > 0.0) out.rotation = q / glm::length(q);
    }
    if (n.scale.size() == 3) out.scale = glm::make_vec3(n.scale.data());
    for (int c : n.children)
      if (c >= 0 && size_t(c) < nodes.size()) scene.nodes[size_t(c)].parent = int(i);
  }
}

}  // namespace prt::gltf
