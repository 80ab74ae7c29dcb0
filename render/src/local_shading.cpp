// Lights inside the scene per pixel (docs/render.md, "Lights inside the scene").
//
// For each light lit per pixel (point, spot, sphere, disk, rectangle; at most
// kMaxLocalLights) a pixel at x with normal n receives E_k(x, n) · visibleShare_k(x):
// - E_k is the light's unoccluded irradiance in closed form, local_lighting.glsl's port of
//   probes/lights' localIrradiance (the disk as its area-matched kLocalDiskSides-gon instead of
//   the 128-gon).
// - visibleShare_k comes from six 90° perspective depth maps around the light's centre (a cube;
//   a spot light too, whose cone the falloff already bounds). Point and spot lights filter 1.5
//   texels; area lights are filtered to their penumbra by PCSS about the centre (the blocker
//   search and filter radii in local_lighting.glsl), so a large light's shadow is soft, if not
//   exactly its share.
// Emissive surfaces are not lit here: their shadowed light comes at the vertices
// (FrameLightingSettings::localPerPixel keeps it there), with the bounces of every light.
#include "local_shading.h"

#include <algorithm>
#include <cmath>

#include "prt/error.h"
#include "renderer_impl.h"

namespace prt::render {

int localShaderType(const LocalLight& light) {
  switch (light.type) {
    case LocalLight::Type::Point:
      return 0;
    case LocalLight::Type::Spot:
      return 1;
    case LocalLight::Type::Sphere:
      return 2;
    case LocalLight::Type::Disk:
      return 3;
    case LocalLight::Type::Rectangle:
      return 4;
    default:
      return -1;
  }
}

std::array<glm::dmat4, 6> cubeFaces(const glm::dvec3& centre, double nearPlane, double farPlane) {
  // Perspective, 90°, square, depth 0 at the near plane and 1 at the far one.
  glm::dmat4 proj(0.0);
  proj[0][0] = proj[1][1] = 1.0;
  proj[2][2] = farPlane / (nearPlane - farPlane);
  proj[2][3] = -1.0;
  proj[3][2] = nearPlane * farPlane / (nearPlane - farPlane);
  const glm::dvec3 axes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  std::array<glm::dmat4, 6> faces;
  for (int f = 0; f < 6; ++f) {
    const glm::dvec3 forward = axes[f];
    const glm::dvec3 up = std::abs(forward.y) > 0.5 ? glm::dvec3(0, 0, 1) : glm::dvec3(0, 1, 0);
    const glm::dvec3 right = glm::normalize(glm::cross(forward, up));
    const glm::dvec3 trueUp = glm::cross(right, forward);
    glm::dmat4 view(1.0);  // world -> camera looking down −Z along `forward`
    for (int i = 0; i < 3; ++i) {
      view[i][0] = right[i];
      view[i][1] = trueUp[i];
      view[i][2] = -forward[i];
    }
    view[3] = glm::dvec4(-glm::dot(right, centre), -glm::dot(trueUp, centre), glm::dot(forward, centre), 1.0);
    faces[size_t(f)] = proj * view;
  }
  return faces;
}

void Renderer::Impl::ensureLocalMaps(int size, int layers) {
  ensureDepthArray(localMaps, size, layers, "local shadow maps");
}

// The uniforms of local_lighting.glsl, per DIRECT program the frame uses.
void Renderer::Impl::setLocalUniforms(const Frame& frame, const FramePlan& plan, const LocalFrameUniforms& u) {
  auto set = [&](const Program& p) {
    auto loc = [&](const char* name) { return gl.GetUniformLocation(p.id, name); };
    gl.ProgramUniform1i(p.id, loc("uLocalCount"), GLint(u.pos.size()));
    gl.ProgramUniform1i(p.id, loc("uLocalShadowed"), u.shadowed ? 1 : 0);
    if (u.pos.empty()) return;
    const GLsizei n = GLsizei(u.pos.size());
    gl.ProgramUniform4fv(p.id, loc("uLocalPos"), n, &u.pos[0].x);
    gl.ProgramUniform4fv(p.id, loc("uLocalDir"), n, &u.dir[0].x);
    gl.ProgramUniform4fv(p.id, loc("uLocalUp"), n, &u.up[0].x);
    gl.ProgramUniform4fv(p.id, loc("uLocalColor"), n, &u.color[0].x);
    gl.ProgramUniform4fv(p.id, loc("uLocalShape"), n, &u.shape[0].x);
    gl.ProgramUniform1i(p.id, loc("uLocalMapSize"), u.mapSize);
    gl.ProgramUniform1f(p.id, loc("uLocalFar"), u.farPlane);
    if (!u.matrices.empty())
      gl.ProgramUniformMatrix4fv(p.id, loc("uLocalMatrix"), GLsizei(u.matrices.size()), GL_FALSE, &u.matrices[0][0][0]);
  };
  if (plan.bakedExtra & kVariantDirect)
    for (const Instance& in : instances) set(bakedProgram(variantOf(in, plan.bakedExtra)));
  if (plan.receiverExtra & kVariantDirect)
    for (const Instance& in : receivers) set(receiverProgram(frame.probeLookup, variantOf(in, plan.receiverExtra)));
  checkError("setting the lights inside the scene");
}

// The lights' uniforms, and their cube maps drawn when Frame::shadows.enabled: every caster, both
// faces, into six layers per light.
void Renderer::Impl::drawLocalShadows(const Frame& frame, const FramePlan& plan) {
  LocalFrameUniforms u;
  const double diag = std::max(double(glm::length(boundsMax - boundsMin)), 1e-3);
  const double farPlane = 2.0 * diag, nearPlane = std::max(1e-4 * diag, 1e-4);
  u.farPlane = float(farPlane);
  for (const LocalLight& l : frame.local) {
    const int type = localShaderType(l);
    if (type < 0) continue;
    const double cosInner = std::cos(l.innerCone), cosOuter = std::cos(l.outerCone);
    const double scale = 1.0 / std::max(0.001, cosInner - cosOuter);
    const bool punctual = l.punctual();
    const double size = type == 4 ? 0.5 * std::hypot(l.width, l.height) : l.radius;
    u.pos.emplace_back(glm::vec3(l.position), float(type));
    u.dir.emplace_back(glm::vec3(l.direction), float(l.range));
    u.up.emplace_back(glm::vec3(l.up), float(l.width));
    u.color.emplace_back(glm::vec3(punctual ? l.intensity : l.radiance), float(l.height));
    u.shape.emplace_back(float(scale), float(-cosOuter * scale), float(punctual ? 0.0 : size), float(nearPlane));
    for (const glm::dmat4& m : cubeFaces(l.position, nearPlane, farPlane)) u.matrices.emplace_back(m);
  }
  u.shadowed = frame.shadows.enabled && !u.pos.empty();
  u.mapSize = std::min(frame.shadows.mapSize, kLocalMapSize);
  if (u.shadowed) {
    const int layers = int(u.matrices.size());
    ensureLocalMaps(u.mapSize, layers);
    std::vector<glm::dmat4> motions;
    glm::dvec3 lo, hi;
    shadowCasterBounds(frame, plan.drawReceivers, lo, hi, motions);
    drawDepthLayers(localMaps, u.mapSize, u.matrices, motions, plan.drawReceivers);
    gl.BindTextureUnit(kLocalShadowUnit, localMaps.texture);
    checkError("drawing the local shadow maps");
    stats.localShadowMaps = layers;
    stats.localMapSize = u.mapSize;
  }
  stats.localLights = u.pos.size();
  setLocalUniforms(frame, plan, u);
}

}  // namespace prt::render
