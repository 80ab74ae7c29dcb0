// The shadow-map pass (docs/render.md, "Direct lights and their shadows"): the maps fitted to
// the casters and the view (planShadows), every opaque baked instance and every drawn receiver
// (at the frame's time) into one depth layer per light and cascade, then the direct uniforms of
// the DIRECT programs. BLEND and transmissive instances cast through their material
// (cutoutDepthProgram).
#include "shadow_pass.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>

#include "direct_shading.h"
#include "prt/error.h"
#include "renderer_impl.h"
#include "shader_sources.h"

namespace prt::render {

glm::dmat4 ShadowLayer::viewProj() const {
  glm::dmat4 s(1.0);
  s[0][0] = 2.0 / side;
  s[1][1] = 2.0 / side;
  s[3][0] = -1.0;
  s[3][1] = -1.0;
  s[2][2] = 1.0 / range;
  return s * worldToMap;
}

namespace {

using Box = std::array<glm::dvec3, 8>;

// The view depths where the cascades begin and end (one cascade: {nearest, farthest}); sets
// plan.cascades and plan.cascadeFar.
std::vector<double> cascadeSplits(const CameraView& camera, const Box& box, double diag, int heightPixels, int mapSize,
                                  int maxCascades, ShadowPlan& plan) {
  // View depths the casters' box spans.
  double dNear = 1e300, dFar = -1e300;
  for (const glm::dvec3& c : box) {
    const double d = glm::dot(c - plan.viewOrigin, plan.viewForward);
    dNear = std::min(dNear, d);
    dFar = std::max(dFar, d);
  }
  // The nearest depth that matters: the box's, but at least a quarter of the farthest (a camera
  // inside the box would otherwise ask for texels as fine as its near plane; what lies closer
  // than a quarter of the view's depth gets the first cascade's texels).
  const double farthest = std::max(dFar, camera.znear * 1.001 + 1e-9);
  const double nearest = std::clamp(std::max(dNear, 0.25 * farthest), camera.znear, farthest / 1.001);
  const double tanY = std::tan(0.5 * camera.yfov);
  std::vector<double> splits = {nearest, farthest};
  if (camera.perspective && maxCascades > 1) {
    // One map over the whole box has texels of at most diag / mapSize; a pixel at depth z covers
    // z · 2 tan(fov/2) / height. Cascades only where that texel exceeds two pixels at the
    // nearest visible depth; each then covers a depth ratio of about 3 (practical split scheme,
    // Zhang et al. 2006: λ = 0.75 of logarithmic, the rest uniform).
    const double pixel = nearest * 2.0 * tanY / std::max(heightPixels, 1);
    if (diag / mapSize > 2.0 * pixel) {
      const int n = std::clamp(int(std::ceil(std::log(farthest / nearest) / std::log(3.0))), 1, maxCascades);
      splits.assign(size_t(n) + 1, 0.0);
      for (int i = 0; i <= n; ++i) {
        const double f = double(i) / n;
        splits[size_t(i)] =
            0.75 * nearest * std::pow(farthest / nearest, f) + 0.25 * (nearest + (farthest - nearest) * f);
      }
    }
  }
  plan.cascades = int(splits.size()) - 1;
  plan.cascadeFar = glm::dvec4(1e30);
  for (int c = 0; c + 1 < plan.cascades && c < 4; ++c) plan.cascadeFar[c] = splits[size_t(c) + 1];
  return splits;
}

// Light space of one light: e3 = −d (depth grows away from the light), e1, e2 across; and the
// casters' box in it (bLo.z, bHi.z widened by a little).
struct LightFrame {
  glm::dvec3 e1, e2, e3;
  glm::dvec3 bLo{1e300}, bHi{-1e300};
};

LightFrame lightFrame(const DirectLight& light, const Box& box, double diag) {
  LightFrame f;
  f.e3 = -glm::normalize(light.direction);
  const glm::dvec3 helper = std::abs(f.e3.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
  f.e1 = glm::normalize(glm::cross(helper, f.e3));
  f.e2 = glm::cross(f.e3, f.e1);
  for (const glm::dvec3& c : box) {
    const glm::dvec3 l(glm::dot(c, f.e1), glm::dot(c, f.e2), glm::dot(c, f.e3));
    f.bLo = glm::min(f.bLo, l);
    f.bHi = glm::max(f.bHi, l);
  }
  const double eps = 1e-3 * diag;
  f.bLo.z -= eps;
  f.bHi.z += eps;
  return f;
}

// The map of cascade c of one light: the slice of the view between splits[c] and splits[c + 1],
// in light space, clipped to the casters' box, grown by the filter's margin and snapped.
ShadowLayer fitLayer(const LightFrame& f, double tanR, const CameraView& camera, double aspect, const ShadowPlan& plan,
                     const std::vector<double>& splits, int c, double diag, int mapSize) {
  const glm::dvec3 right = glm::normalize(glm::dvec3(camera.cameraToWorld[0]));
  const glm::dvec3 up = glm::normalize(glm::dvec3(camera.cameraToWorld[1]));
  const double tanY = std::tan(0.5 * camera.yfov);
  glm::dvec2 sLo(1e300), sHi(-1e300);
  for (int k = 0; k < 8; ++k) {
    // The first slice starts at the near plane: what lies closer than `nearest` is in it too.
    const double z = c == 0 && !(k & 1) ? std::min(camera.znear, splits[0]) : splits[size_t(c) + (k & 1)];
    const double hh = camera.perspective ? z * tanY : camera.ymag, hw = hh * aspect;
    const glm::dvec3 p = plan.viewOrigin + plan.viewForward * z + right * (k & 2 ? hw : -hw) + up * (k & 4 ? hh : -hh);
    const glm::dvec2 l(glm::dot(p, f.e1), glm::dot(p, f.e2));
    sLo = glm::min(sLo, l);
    sHi = glm::max(sHi, l);
  }
  const double range = f.bHi.z - f.bLo.z;
  glm::dvec2 xLo = glm::max(sLo, glm::dvec2(f.bLo)), xHi = glm::min(sHi, glm::dvec2(f.bHi));
  xHi = glm::max(xHi, xLo + 1e-6 * diag);
  double side = std::max(xHi.x - xLo.x, xHi.y - xLo.y);
  // A margin for the search and filter disks of receivers at the edge of the slice, and two
  // texels for the snapping below.
  const double grow = std::min(tanR * range, 0.25 * side) + 4.0 * side / mapSize;
  side += 2.0 * grow + 2.0 * side / mapSize;
  // Texel snapping (stable cascades, Valient 2008): the side is rounded up to a step of a
  // ladder fixed by the casters' box (diag · 2^(k/8)) and the map's corner down to a whole
  // texel of light space, so the texel grid stays put in the world while the camera moves
  // and jumps only when the side crosses a step (texels at most 9% coarser): shadow edges
  // do not crawl from frame to frame. The corner moves by less than a texel, which the
  // texels added above cover.
  side = diag * std::exp2(std::ceil(8.0 * std::log2(side / diag) - 1e-9) / 8.0);
  const double texel = side / mapSize;
  const glm::dvec2 centre = 0.5 * (xLo + xHi), corner = glm::floor((centre - 0.5 * side) / texel) * texel;
  ShadowLayer layer;
  layer.side = side;
  layer.range = range;
  layer.texel = texel;
  layer.tanRadius = tanR;
  const glm::dvec3 axes[3] = {f.e1, f.e2, f.e3};
  const double offset[3] = {corner.x, corner.y, f.bLo.z};
  layer.worldToMap = glm::dmat4(1.0);
  for (int r = 0; r < 3; ++r) {
    for (int col = 0; col < 3; ++col) layer.worldToMap[col][r] = axes[r][col];
    layer.worldToMap[3][r] = -offset[r];
  }
  return layer;
}

}  // namespace

ShadowPlan planShadows(const std::vector<DirectLight>& lights, const CameraView& camera, double aspect,
                       int heightPixels, const glm::dvec3& lo, const glm::dvec3& hi, int mapSize, int maxCascades) {
  PRT_CHECK(mapSize >= 1);
  ShadowPlan plan;
  plan.viewOrigin = glm::dvec3(camera.cameraToWorld[3]);
  plan.viewForward = -glm::normalize(glm::dvec3(camera.cameraToWorld[2]));
  Box box;
  for (int i = 0; i < 8; ++i)
    box[size_t(i)] = glm::dvec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
  const double diag = std::max(glm::length(hi - lo), 1e-6);
  const std::vector<double> splits = cascadeSplits(camera, box, diag, heightPixels, mapSize, maxCascades, plan);
  for (const DirectLight& light : lights) {
    const LightFrame f = lightFrame(light, box, diag);
    const double tanR = light.radius < kPointSunRadians ? 0.0 : std::tan(light.radius);
    for (int c = 0; c < plan.cascades; ++c)
      plan.layers.push_back(fitLayer(f, tanR, camera, aspect, plan, splits, c, diag, mapSize));
  }
  return plan;
}

// A depth texture array of `layers` square maps of `size` texels and its framebuffer in `maps`,
// made anew unless `maps` already holds that size and as many layers; `what` names them in errors.
void Renderer::Impl::ensureDepthArray(ShadowMaps& maps, int size, int layers, const char* what) {
  if (maps.texture && size == maps.size && layers <= maps.layers) return;
  GLint maxSize = 0, maxLayers = 0;
  gl.GetIntegerv(GL_MAX_TEXTURE_SIZE, &maxSize);
  gl.GetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &maxLayers);
  if (size > maxSize || layers > maxLayers)
    throw Error(cat("render: ", layers, " ", what, " of ", size, "x", size, " exceed the GL's limits (", maxSize,
                    " texels a side, ", maxLayers, " layers)"));
  maps = ShadowMaps{};
  GlTexture texture = createTexture(gl, GL_TEXTURE_2D_ARRAY);
  gl.TextureStorage3D(texture, 1, GL_DEPTH_COMPONENT32F, size, size, layers);
  gl.TextureParameteri(texture, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  gl.TextureParameteri(texture, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  gl.TextureParameteri(texture, GL_TEXTURE_COMPARE_MODE, GL_NONE);
  gl.TextureParameteri(texture, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  gl.TextureParameteri(texture, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  GlFramebuffer framebuffer = createFramebuffer(gl);
  gl.NamedFramebufferTextureLayer(framebuffer, GL_DEPTH_ATTACHMENT, texture, 0, 0);
  gl.NamedFramebufferDrawBuffer(framebuffer, GL_NONE);
  gl.NamedFramebufferReadBuffer(framebuffer, GL_NONE);
  const GLenum status = gl.CheckNamedFramebufferStatus(framebuffer, GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    throw Error(cat("GL: ", what, " framebuffer incomplete (", glErrorName(status), ")"));
  checkError(what);
  maps = ShadowMaps{std::move(texture), std::move(framebuffer), size, layers};
}

void Renderer::Impl::ensureShadowMaps(int size, int layers) {
  ensureDepthArray(shadowMaps, size, layers, "shadow maps");
}

// The casters' box: the scene's bounds and, where they moved, the receivers' at the frame's
// time; `motions` gets each receiver's motion.
void Renderer::Impl::shadowCasterBounds(const Frame& frame, bool withReceivers, glm::dvec3& lo, glm::dvec3& hi,
                                        std::vector<glm::dmat4>& motions) const {
  lo = glm::dvec3(boundsMin);
  hi = glm::dvec3(boundsMax);
  for (const Instance& in : receivers) {
    motions.push_back(instanceMotion(animation, in.placement, frame.time));
    if (!withReceivers || in.restLo.x > in.restHi.x) continue;
    for (int i = 0; i < 8; ++i) {
      const glm::dvec3 c(i & 1 ? in.restHi.x : in.restLo.x, i & 2 ? in.restHi.y : in.restLo.y,
                         i & 4 ? in.restHi.z : in.restLo.z);
      const glm::dvec3 w(motions.back() * glm::dvec4(c, 1.0));
      lo = glm::min(lo, w);
      hi = glm::max(hi, w);
    }
  }
}

// One caster into the current layer: opaque casters with the plain depth program, those that let
// light through with their material's. `current`: the program in use, switched only between
// opaque and cutout casters.
void Renderer::Impl::castShadow(const Instance& in, const glm::mat4& model, const glm::mat4& viewProj,
                                GLuint& current) {
  const bool cutout = in.blend || (in.variant & kVariantMask);
  const Program& p = cutout ? cutoutDepthProgram(in.variant) : depthProgram;
  if (p.id != current) {
    gl.UseProgram(p.id);
    gl.ProgramUniformMatrix4fv(p.id, p.viewProj, 1, GL_FALSE, &viewProj[0][0]);
    current = p.id;
  }
  gl.ProgramUniformMatrix4fv(p.id, p.model, 1, GL_FALSE, &model[0][0]);
  if (cutout) setMaterialUniforms(p, in);
  gl.BindVertexArray(in.vao);
  gl.DrawElements(GL_TRIANGLES, in.indexCount, GL_UNSIGNED_INT, nullptr);
}

// Every layer of `maps` (drawn from viewProj[layer]): both faces of every caster (culling off: a
// double-sided sheet casts from either side), the receivers moved by `motions` where drawn.
void Renderer::Impl::drawDepthLayers(const ShadowMaps& maps, int mapSize, const std::vector<glm::mat4>& viewProj,
                                     const std::vector<glm::dmat4>& motions, bool withReceivers) {
  gl.BindFramebuffer(GL_FRAMEBUFFER, maps.framebuffer);
  gl.Viewport(0, 0, mapSize, mapSize);
  gl.ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  gl.Enable(GL_DEPTH_TEST);
  gl.DepthFunc(GL_LESS);
  gl.Disable(GL_CULL_FACE);
  const float one = 1.0f;
  const glm::mat4 identity(1.0f);
  for (size_t layer = 0; layer < viewProj.size(); ++layer) {
    gl.NamedFramebufferTextureLayer(maps.framebuffer, GL_DEPTH_ATTACHMENT, maps.texture, 0, GLint(layer));
    gl.ClearNamedFramebufferfv(maps.framebuffer, GL_DEPTH, 0, &one);
    GLuint current = 0;
    for (const Instance& in : instances) castShadow(in, identity, viewProj[layer], current);
    if (withReceivers)
      for (size_t k = 0; k < receivers.size(); ++k)
        castShadow(receivers[k], glm::mat4(motions[k]), viewProj[layer], current);
  }
  gl.BindVertexArray(0);
}

// Every layer of `shadows`, the direct lights' maps.
void Renderer::Impl::drawShadowMaps(const ShadowPlan& shadows, const std::vector<glm::dmat4>& motions,
                                    bool withReceivers, int mapSize) {
  ensureShadowMaps(mapSize, int(shadows.layers.size()));
  std::vector<glm::mat4> viewProj;
  for (const auto& layer : shadows.layers) viewProj.emplace_back(layer.viewProj());
  drawDepthLayers(shadowMaps, mapSize, viewProj, motions, withReceivers);
  gl.Finish();
  checkError("drawing the shadow maps");
}

// The direct uniforms, per DIRECT program the frame uses. `maps`: the frame has shadow maps.
void Renderer::Impl::setDirectUniforms(const Frame& frame, const FramePlan& plan, const ShadowPlan& shadows,
                                       bool maps) {
  std::vector<glm::vec4> dirs, irradiance, params;
  std::vector<glm::mat4> matrices;
  for (const DirectLight& l : frame.direct) {
    const double radius = l.radius < kPointSunRadians ? 0.0 : l.radius;
    const double sin2 = std::sin(radius) * std::sin(radius);
    dirs.emplace_back(glm::vec3(glm::normalize(l.direction)), float(sin2));
    irradiance.emplace_back(glm::vec3(l.irradiance), radius > 0.0 ? float(1.0 / std::tan(radius)) : 0.0f);
  }
  for (const ShadowLayer& layer : shadows.layers) {
    matrices.emplace_back(layer.worldToMap);
    params.emplace_back(float(layer.texel), float(layer.range), float(layer.tanRadius), 0.0f);
  }
  const glm::vec4 cascadeFar(shadows.cascadeFar);
  const glm::vec3 origin(shadows.viewOrigin), forward(shadows.viewForward);
  const int mapSize = frame.shadows.mapSize;
  auto set = [&](const Program& p) {
    gl.ProgramUniform1i(p.id, p.directCount, GLint(dirs.size()));
    gl.ProgramUniform1i(p.id, p.shadowed, maps ? 1 : 0);
    gl.ProgramUniform1i(p.id, p.loopStep, 1);
    if (dirs.empty()) return;
    gl.ProgramUniform4fv(p.id, p.directDir, GLsizei(dirs.size()), &dirs[0].x);
    gl.ProgramUniform4fv(p.id, p.directIrradiance, GLsizei(irradiance.size()), &irradiance[0].x);
    if (!maps) return;
    gl.ProgramUniform1i(p.id, p.cascades, shadows.cascades);
    gl.ProgramUniform4fv(p.id, p.cascadeFar, 1, &cascadeFar.x);
    gl.ProgramUniform3fv(p.id, p.viewOrigin, 1, &origin.x);
    gl.ProgramUniform3fv(p.id, p.viewForward, 1, &forward.x);
    gl.ProgramUniform1i(p.id, p.shadowSize, mapSize);
    gl.ProgramUniformMatrix4fv(p.id, p.shadowMatrix, GLsizei(matrices.size()), GL_FALSE, &matrices[0][0][0]);
    gl.ProgramUniform4fv(p.id, p.shadowParams, GLsizei(params.size()), &params[0].x);
  };
  if (plan.bakedExtra)
    for (const Instance& in : instances) set(bakedProgram(variantOf(in, plan.bakedExtra)));
  if (plan.receiverExtra)
    for (const Instance& in : receivers) set(receiverProgram(frame.probeLookup, variantOf(in, plan.receiverExtra)));
  checkError("setting the direct lights");
}

void Renderer::Impl::drawShadows(const Frame& frame, const FramePlan& plan) {
  const auto t0 = std::chrono::steady_clock::now();
  const ShadowSettings& settings = frame.shadows;
  ShadowPlan shadows;
  // No direct light (a frame lit only by a gathered sky detail): no maps, a light count of 0.
  const bool maps = settings.enabled && !frame.direct.empty();
  if (maps) {
    glm::dvec3 lo, hi;
    std::vector<glm::dmat4> motions;
    shadowCasterBounds(frame, plan.drawReceivers, lo, hi, motions);
    const double aspect = double(plan.width) / plan.height;
    shadows =
        planShadows(frame.direct, frame.camera, aspect, plan.height, lo, hi, settings.mapSize, settings.maxCascades);
    drawShadowMaps(shadows, motions, plan.drawReceivers, settings.mapSize);
    stats.shadowMaps = int(shadows.layers.size());
    stats.cascades = shadows.cascades;
    stats.shadowMapSize = settings.mapSize;
  }
  setDirectUniforms(frame, plan, shadows, maps);
  drawLocalShadows(frame, plan);
  stats.shadowMs = msSince(t0);
}

}  // namespace prt::render
