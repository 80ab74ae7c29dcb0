// Rasterizing baked instances with per-vertex SH transfer, and receivers lit per pixel from the
// probe grid (docs/render.md): the renderer's programs and framebuffer, and the frame as passes
// (light update, shadows, opaque, receivers, background, blended, read-back). The scene upload,
// the shadow pass and the background pass have files of their own (renderer_impl.h).
#include "prt/render/renderer.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "camera.h"
#include "direct_shading.h"
#include "probe_shading.h"
#include "prt/error.h"
#include "renderer_impl.h"
#include "shader_sources.h"

namespace prt::render {

namespace {

// The direct lights' SH at `bands` bands (zero without any).
sh::ShRgb directSh(const Frame& frame, int bands) {
  return frame.directLight.size() > 0 ? sh::resize(frame.directLight, bands) : sh::ShRgb(bands);
}

// The light flat ((coefficient i, channel c) at float 3i + c) in vec4 chunks, zero-padded: the
// layout of the attribute transfer (shader_sources.h).
std::vector<glm::vec4> flatLight(const sh::ShRgb& l, int bands) {
  std::vector<glm::vec4> packed(size_t(attributeChunks(bands)), glm::vec4(0.0f));
  for (int i = 0; i < l.size(); ++i)
    for (int c = 0; c < 3; ++c) packed[size_t(3 * i + c) / 4][(3 * i + c) % 4] = l.c[size_t(i)][c];
  return packed;
}

// A colour (and, with `depth`, depth) renderbuffer of `samples` samples attached to `framebuffer`.
GlRenderbuffer attachRenderbuffer(const GlFunctions& gl, GLuint framebuffer, GLenum attachment, GLenum format,
                                  int width, int height, int samples) {
  GlRenderbuffer rb = createRenderbuffer(gl);
  if (samples > 1)
    gl.NamedRenderbufferStorageMultisample(rb, samples, format, width, height);
  else
    gl.NamedRenderbufferStorage(rb, format, width, height);
  gl.NamedFramebufferRenderbuffer(framebuffer, attachment, GL_RENDERBUFFER, rb);
  return rb;
}

void checkComplete(const GlFunctions& gl, GLuint framebuffer, int samples) {
  gl.NamedFramebufferDrawBuffer(framebuffer, GL_COLOR_ATTACHMENT0);
  gl.NamedFramebufferReadBuffer(framebuffer, GL_COLOR_ATTACHMENT0);
  const GLenum status = gl.CheckNamedFramebufferStatus(framebuffer, GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    throw Error(cat("GL: RGBA32F framebuffer of ", samples, " samples incomplete (", glErrorName(status), ")"));
}

void checkFrame(const Frame& frame) {
  if (frame.direct.size() > size_t(kMaxDirectLights))
    throw Error(cat("render: ", frame.direct.size(), " direct lights, at most ", kMaxDirectLights, " per frame"));
  const ShadowSettings& s = frame.shadows;
  if (s.mapSize < 16 || s.mapSize > 8192 || s.maxCascades < 1 || s.maxCascades > kMaxCascades)
    throw Error(cat("render: shadow maps of ", s.mapSize, " texels and ", s.maxCascades,
                    " cascades; expected 16..8192 and 1..", kMaxCascades));
}

}  // namespace

// ---- Programs, linked on first use -------------------------------------------------------

const Program& Renderer::Impl::cutoutDepthProgram(int variant) {
  variant &= kVariantMaterialBits;
  Program& p = cutoutDepthPrograms[size_t(variant)];
  if (!p.id)
    p = linkProgram(gl, withMaterialDefines(cutoutDepthVertexShader(), variant),
                    withMaterialDefines(cutoutDepthFragmentShader(), variant), "shadow map (cutouts)");
  return p;
}

const Program& Renderer::Impl::bakedProgram(int variant) {
  Program& p = programs[size_t(variant)];
  if (!p.id)
    p = linkProgram(gl, withMaterialDefines(bakedVertexShader(bands), variant),
                    withMaterialDefines(bakedFragmentShader(envMaps), variant), "baked");
  return p;
}

const Program& Renderer::Impl::receiverProgram(ProbeLookup lookup, int variant) {
  Program& p = receiverPrograms[size_t(lookup)][size_t(variant)];
  if (!p.id) {
    p = linkProgram(gl, withMaterialDefines(receiverVertexShader(grid->bands, lookup), variant),
                    withMaterialDefines(receiverFragmentShader(grid->bands, lookup, envMaps), variant), "receiver");
    const glm::vec3 origin(grid->origin), spacing(grid->spacing);
    gl.ProgramUniform3fv(p.id, p.origin, 1, &origin.x);
    gl.ProgramUniform3fv(p.id, p.spacing, 1, &spacing.x);
    gl.ProgramUniform3iv(p.id, p.dims, 1, &grid->dims.x);
    gl.ProgramUniform1f(p.id, p.nearZero, float(nearZero(*grid)));
  }
  return p;
}

// ---- The framebuffer -----------------------------------------------------------------------

void Renderer::Impl::ensureFramebuffer(int width, int height, int samples, bool reflections) {
  // A target with the reflections' attachments serves frames without them too.
  if (target.framebuffer && width == target.width && height == target.height && samples == target.samples &&
      (target.reflections || !reflections))
    return;
  GLint maxSize = 0, maxSamples = 0;
  gl.GetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &maxSize);
  gl.GetIntegerv(GL_MAX_SAMPLES, &maxSamples);
  if (width <= 0 || height <= 0 || width > maxSize || height > maxSize)
    throw Error(cat("render: frame size ", width, "x", height, " outside 1..", maxSize));
  if (samples < 1 || samples > std::max(maxSamples, 1) || (samples & (samples - 1)) != 0)
    throw Error(
        cat("render: ", samples, " samples per pixel; this GL allows 1, 2, 4 ... up to ", std::max(maxSamples, 1)));
  target = Target{};
  Target t;
  t.framebuffer = createFramebuffer(gl);
  t.color = attachRenderbuffer(gl, t.framebuffer, GL_COLOR_ATTACHMENT0, GL_RGBA32F, width, height, samples);
  t.width = width;
  t.height = height;
  if (reflections && samples == 1)
    attachReflectionTargets(t);
  else
    t.depth = attachRenderbuffer(gl, t.framebuffer, GL_DEPTH_ATTACHMENT, GL_DEPTH_COMPONENT32F, width, height, samples);
  checkComplete(gl, t.framebuffer, samples);
  if (samples > 1) {
    t.resolveFramebuffer = createFramebuffer(gl);
    t.resolveColor = attachRenderbuffer(gl, t.resolveFramebuffer, GL_COLOR_ATTACHMENT0, GL_RGBA32F, width, height, 1);
    checkComplete(gl, t.resolveFramebuffer, 1);
  }
  // The GL may give more samples than asked for (llvmpipe: 4 for 2).
  GLint actual = 0;
  gl.GetNamedRenderbufferParameteriv(t.color, GL_RENDERBUFFER_SAMPLES, &actual);
  t.actualSamples = std::max(actual, 1);
  checkError("creating the framebuffer");
  t.samples = samples;
  target = std::move(t);
}

// ---- The renderer ----------------------------------------------------------------------------

Renderer::Renderer(GlContext& context, const Scene& scene) : impl_(std::make_unique<Impl>(context)) {
  bool anyReceiver = false;
  for (const MeshInstance& m : scene.meshes) anyReceiver |= m.receiverOnly;
  if (scene.transferBands < 0 || scene.transferBands > sh::kMaxBands || (scene.transferBands == 0 && !anyReceiver))
    throw Error(cat(scene.path, ": holds no baked transfer (run prt bake first)"));
  impl_->bands = scene.transferBands;
  // On a throw, impl_ goes with the GL objects made so far, with this context current.
  context.makeCurrent();
  impl_->flatProgram = linkProgram(impl_->gl, flatVertexShader(), flatFragmentShader(), "flat");
  impl_->depthProgram = linkProgram(impl_->gl, flatVertexShader(), depthFragmentShader(), "shadow map");
  impl_->upload(scene);
}

Renderer::~Renderer() {
  // GL objects belong to the context: make it current so they are deleted there, not in
  // whichever context happens to be current. A failure here cannot be reported; leak the
  // objects (and the Impl that holds them) instead.
  try {
    impl_->context.makeCurrent();
  } catch (const Error&) {
    (void)impl_.release();
    return;
  }
  impl_.reset();
}

void Renderer::setProbes(const ProbeGrid& grid) {
  impl_->context.makeCurrent();
  impl_->uploadProbes(grid);
}

ImageRgb Renderer::render(const CameraView& camera, const sh::ShRgb& light) {
  return render(camera, light, impl_->context.width(), impl_->context.height());
}

ImageRgb Renderer::render(const CameraView& camera, const sh::ShRgb& light, int width, int height) {
  Frame f;
  f.camera = camera;
  f.light = light;
  f.width = width;
  f.height = height;
  return render(f);
}

ImageRgb Renderer::render(const Frame& frame) {
  Impl& r = *impl_;
  checkFrame(frame);
  r.context.makeCurrent();
  FramePlan plan = r.planFrame(frame);
  r.updateLight(frame, plan);

  const auto t1 = std::chrono::steady_clock::now();
  r.ensureFramebuffer(plan.width, plan.height, frame.samples, plan.reflections);
  r.stats.samples = r.target.actualSamples;
  r.stats.shadowMs = 0.0;
  r.stats.shadowMaps = r.stats.cascades = r.stats.shadowMapSize = r.stats.localShadowMaps = 0;
  r.stats.localLights = 0;
  r.stats.localMapSize = 0;
  if (plan.bakedSplit || plan.receiverSplit) r.drawShadows(frame, plan);
  r.beginFrame(frame, plan);
  r.beginMaterialFrame(frame, plan);
  if (plan.reflections) r.drawReflectionInputs(true);
  r.drawOpaque(frame, plan);
  // After the baked instances, so that the depth test rejects hidden receiver pixels before
  // their (costly) probe lookup runs.
  if (plan.drawReceivers) r.drawReceivers(frame, plan);
  if (plan.reflections) r.drawReflectionInputs(false);
  if (!plan.flat && frame.background) r.drawBackground(*frame.background, frame.camera, plan.width, plan.height);
  if (plan.reflections) r.drawReflections(frame, plan);
  if (!plan.flat) r.drawBlended(frame, plan);
  r.gl.BindVertexArray(0);
  r.gl.Finish();
  r.checkError("drawing the frame");
  r.stats.drawMs = msSince(t1);

  return r.readBack(plan.width, plan.height);
}

// ---- The frame's passes ----------------------------------------------------------------------

// Direct lights: lit per pixel where the transfer holds its direct part (bakedSplit,
// receiverSplit), else through SH with the rest of the light (warned once).
FramePlan Renderer::Impl::planFrame(const Frame& frame) {
  FramePlan plan;
  plan.width = frame.width > 0 ? frame.width : context.width();
  plan.height = frame.height > 0 ? frame.height : context.height();
  plan.flat = frame.shading == Shading::Flat;
  plan.drawReceivers = grid != nullptr && !receivers.empty();
  const bool anyDirect = !plan.flat && !frame.direct.empty();
  const bool anyLocal = !plan.flat && !frame.local.empty();  // lights inside the scene (local_shading.cpp)
  // A gathered irradiance (Frame::directBounce: the sky's detail) needs the split shader even
  // without direct lights.
  plan.bakedSplit = (anyDirect || anyLocal || (!plan.flat && frame.directBounce)) && bakedDirect && !instances.empty();
  plan.receiverSplit = (anyDirect || anyLocal) && plan.drawReceivers && grid->hasDirect();
  if (anyDirect && !instances.empty() && !bakedDirect && !warnedBakedDirect) {
    warnedBakedDirect = true;
    warnings.push_back(cat("the baked scene has no direct part of its transfer (baked by an older prt): its ",
                           frame.direct.size(),
                           " direct light(s) are lit through SH, without exact shadows; bake "
                           "again for them"));
  }
  if (anyDirect && plan.drawReceivers && !grid->hasDirect() && !warnedProbeDirect) {
    warnedProbeDirect = true;
    warnings.push_back(cat("the probe grid has no direct part (baked by an older prt): receivers get the ",
                           frame.direct.size(),
                           " direct light(s) through SH, without exact shadows; bake the "
                           "probes again for them"));
  }
  stats.directBaked = plan.bakedSplit ? frame.direct.size() : 0;
  stats.directReceivers = plan.receiverSplit ? frame.direct.size() : 0;
  const int material = !plan.flat && frame.materials == MaterialShading::Full ? kVariantFullMaterial : 0;
  plan.bakedExtra = (plan.bakedSplit ? kVariantDirect : 0) | material;
  plan.receiverExtra = (plan.receiverSplit ? kVariantDirect : 0) | (plan.drawReceivers ? material : 0);
  plan.reflections = material && frame.screenReflections && frame.samples == 1;
  // The MATERIAL programs compile the reflected maps' count in: linked again when it changes
  // (a rig's maps stay the same across its frames), before the light update, which sets the
  // light on the linked programs.
  const int maps = material && frame.environment ? int(frame.environment->maps.size()) : 0;
  if (material && maps != envMaps) {
    if (maps > kMaxReflectedMaps)
      throw Error(cat("render: ", maps, " environment maps to reflect, at most ", kMaxReflectedMaps));
    envMaps = maps;
    for (int v = 0; v < kVariants; ++v) {
      if (!(v & kVariantFullMaterial)) continue;
      programs[size_t(v)] = Program{};
      for (auto& lookup : receiverPrograms) lookup[size_t(v)] = Program{};
    }
  }
  if (material)
    for (const Instance& in : instances) bakedProgram(variantOf(in, plan.bakedExtra));
  return plan;
}

// Light update: the baked instances' light uniform, and the probes' incident radiance
// c_p = M_p · l (CPU, TBB over probes) copied into the buffer the receivers read.
void Renderer::Impl::updateLight(const Frame& frame, const FramePlan& plan) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!plan.flat && bands > 0) updateBakedLight(frame, plan);
  if (!plan.flat && plan.drawReceivers) updateReceiverLight(frame, plan);
  checkError("updating the light");
  stats.lightMs = msSince(t0);
}

void Renderer::Impl::updateBakedLight(const Frame& frame, const FramePlan& plan) {
  // The whole light through t; with the split, t⁰ · directSh is taken off in the shader, or,
  // with a gathered bounce (Frame::directBounce), directSh stays out and the bounce is added.
  sh::ShRgb l = sh::resize(frame.light, bands);
  const bool gathered = plan.bakedSplit && frame.directBounce != nullptr;
  const sh::ShRgb dl = gathered ? sh::ShRgb(bands) : directSh(frame, bands);
  l += dl;
  if (plan.bakedSplit) {
    uploadBounce(gathered ? frame.directBounce : nullptr, gathered ? frame.directBounceBack : nullptr);
    for (const Instance& in : instances) {
      const Program& p = bakedProgram(variantOf(in, plan.bakedExtra));
      gl.ProgramUniform3fv(p.id, p.directSh, dl.size(), &dl.c[0].x);
    }
  }
  const std::vector<glm::vec4> packed = flatLight(l, bands);
  // The light whose direct part t⁰ · sky reaches a vertex unoccluded (MATERIAL programs: what
  // is left of e is the light its surroundings send, baked_vertex.glsl's vFill).
  const sh::ShRgb sky = plan.bakedSplit ? sh::resize(frame.light, bands) : l;
  for (const Program& p : programs) {
    if (!p.id) continue;
    if (p.skySh >= 0) gl.ProgramUniform3fv(p.id, p.skySh, sky.size(), &sky.c[0].x);
    if (bands <= kMaxAttributeBands)
      gl.ProgramUniform4fv(p.id, p.light, GLsizei(packed.size()), &packed[0].x);
    else
      gl.ProgramUniform3fv(p.id, p.light, l.size(), &l.c[0].x);
  }
}

void Renderer::Impl::updateReceiverLight(const Frame& frame, const FramePlan& plan) {
  const ProbeGrid& g = *grid;
  sh::ShRgb l = sh::resize(frame.light, g.bands);
  const sh::ShRgb dl = directSh(frame, g.bands);
  // Outside the grid (M = I, M⁰ = I) the split leaves the light without the direct lights' SH.
  if (!plan.receiverSplit) l += dl;
  const std::vector<glm::vec4> packedLight = packLight(g.bands, l);
  for (const Instance& in : receivers) {
    const Program& p = receiverProgram(frame.probeLookup, variantOf(in, plan.receiverExtra));
    gl.ProgramUniform4fv(p.id, p.light, GLsizei(packedLight.size()), &packedLight[0].x);
  }
  if (g.probeCount() > 0) {
    std::vector<glm::vec3> relit = plan.receiverSplit ? relightProbes(g, l, dl) : relightProbes(g, l);
    if (frame.probeBounce && (plan.receiverSplit || frame.direct.empty())) {
      PRT_CHECK_EQ(frame.probeBounce->size(), relit.size());
      for (size_t i = 0; i < relit.size(); ++i) relit[i] += (*frame.probeBounce)[i];
    }
    packRadiance(g.bands, relit, radiance);
    gl.NamedBufferSubData(probes.radiance, 0, GLsizeiptr(radiance.size() * sizeof(glm::vec4)), radiance.data());
  }
}

// The camera's view-projection (plan.viewProj) and the cleared framebuffer.
void Renderer::Impl::beginFrame(const Frame& frame, FramePlan& plan) {
  const CameraView& camera = frame.camera;
  const double aspect = double(plan.width) / plan.height;
  const glm::dmat4 view = glm::inverse(camera.cameraToWorld);
  double orthoFar = 1.0;
  for (int i = 0; i < 8; ++i) {
    const glm::dvec3 corner(i & 1 ? boundsMax.x : boundsMin.x, i & 2 ? boundsMax.y : boundsMin.y,
                            i & 4 ? boundsMax.z : boundsMin.z);
    orthoFar = std::max(orthoFar, -(view * glm::dvec4(corner, 1.0)).z * 1.01 + camera.znear);
  }
  // Receivers may move outside the rest-pose bounds: extend the orthographic far plane.
  plan.viewProj = glm::mat4(projection(camera, aspect, 4.0 * orthoFar) * view);
  gl.BindFramebuffer(GL_FRAMEBUFFER, target.framebuffer);
  gl.Viewport(0, 0, plan.width, plan.height);
  gl.ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  gl.Enable(GL_DEPTH_TEST);
  gl.DepthFunc(GL_GREATER);
  const float black[4] = {0, 0, 0, 0};
  const float farDepth = 0.0f;
  gl.ClearNamedFramebufferfv(target.framebuffer, GL_COLOR, 0, black);
  gl.ClearNamedFramebufferfv(target.framebuffer, GL_DEPTH, 0, &farDepth);
  stats.triangles = stats.receiverTriangles = 0;
}

void Renderer::Impl::setMaterialUniforms(const Program& p, const Instance& in) {
  gl.ProgramUniform4fv(p.id, p.baseColor, 1, &in.baseColor.x);
  gl.ProgramUniform1f(p.id, p.opacity, in.opacity);
  if (p.alphaCutoff >= 0) gl.ProgramUniform1f(p.id, p.alphaCutoff, in.alphaCutoff);
  if (in.texture) gl.BindTextureUnit(0, in.texture);
  if (in.transmissionTexture) gl.BindTextureUnit(kTransmissionUnit, in.transmissionTexture);
  if (p.material >= 0) setFullMaterialUniforms(p, in);
}

void Renderer::Impl::drawInstance(const Program& p, const Instance& in, bool mirrored, bool flat) {
  // The loader already wound every instance counter-clockwise in world space (it swaps two
  // corners under mirroring transforms), so only a mirroring motion flips the front face.
  // The front face decides gl_FrontFacing (the side a two-sided instance shows) as well.
  gl.FrontFace(mirrored ? GL_CW : GL_CCW);
  if (in.doubleSided) {
    gl.Disable(GL_CULL_FACE);
  } else {
    gl.Enable(GL_CULL_FACE);
    gl.CullFace(GL_BACK);
  }
  if (!flat) setMaterialUniforms(p, in);
  gl.BindVertexArray(in.vao);
  gl.DrawElements(GL_TRIANGLES, in.indexCount, GL_UNSIGNED_INT, nullptr);
  stats.triangles += in.triangles;
}

// A baked instance's storage buffers (shader_sources.h); a baked instance never mirrors.
bool Renderer::Impl::placeBaked(const Instance& in, const FramePlan& plan) {
  if (plan.flat) return false;
  if (bands > kMaxAttributeBands) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, in.transfer);
  if (in.transferBack) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, in.transferBack);
  if (plan.bakedSplit) {
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, in.transferDirect);
    if (in.transferDirectBack) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, in.transferDirectBack);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, in.directBounce);
    if (in.directBounceBack) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, in.directBounceBack);
  }
  if (plan.bakedExtra & kVariantFullMaterial) bindMaterialBuffers(in, plan.bakedSplit);
  return false;
}

// A receiver's motion at the frame's time; returns whether it mirrors.
bool Renderer::Impl::placeReceiver(const Program& p, const Instance& in, const Frame& frame, bool flat) {
  const glm::dmat4 motion = instanceMotion(animation, in.placement, frame.time);
  const glm::dmat3 linear(motion);
  // Cofactor matrix = det · inverse transpose: maps normals, defined even for singular
  // motions; its scale does not matter (the shader normalises), its sign does.
  glm::dmat3 cof(glm::cross(linear[1], linear[2]), glm::cross(linear[2], linear[0]), glm::cross(linear[0], linear[1]));
  const bool mirrored = glm::determinant(linear) < 0.0;
  if (mirrored) cof = -cof;
  const glm::mat4 model(motion);
  const glm::mat3 normalMatrix(cof);
  gl.ProgramUniformMatrix4fv(p.id, p.model, 1, GL_FALSE, &model[0][0]);
  if (!flat) gl.ProgramUniformMatrix3fv(p.id, p.normalMatrix, 1, GL_FALSE, &normalMatrix[0][0]);
  stats.receiverTriangles += in.triangles;
  return mirrored;
}

// Draws the opaque instances of `list` (every instance with flat shading) grouped by program:
// each material variant's, or the flat one for all.
void Renderer::Impl::drawOpaqueList(const std::vector<Instance>& list, const std::array<Program, kVariants>& variants,
                                    bool receiverList, int extra, const Frame& frame, const FramePlan& plan) {
  const glm::mat4 identity(1.0f);
  for (int variant = 0; variant < (plan.flat ? 1 : kVariants); ++variant) {
    const Program& p = plan.flat ? flatProgram : variants[size_t(variant)];
    bool used = false;
    for (const Instance& in : list) {
      if (!plan.flat && (variantOf(in, extra) != variant || in.blend)) continue;
      if (!used) {
        gl.UseProgram(p.id);
        gl.ProgramUniformMatrix4fv(p.id, p.viewProj, 1, GL_FALSE, &plan.viewProj[0][0]);
        if (plan.flat) gl.ProgramUniformMatrix4fv(p.id, p.model, 1, GL_FALSE, &identity[0][0]);
        used = true;
      }
      const bool mirrored = receiverList ? placeReceiver(p, in, frame, plan.flat) : placeBaked(in, plan);
      drawInstance(p, in, mirrored, plan.flat);
    }
  }
}

void Renderer::Impl::drawOpaque(const Frame& frame, const FramePlan& plan) {
  if (!plan.flat && (plan.bakedSplit || plan.receiverSplit) && shadowMaps.texture)
    gl.BindTextureUnit(kShadowMapUnit, shadowMaps.texture);
  drawOpaqueList(instances, programs, false, plan.bakedExtra, frame, plan);
}

void Renderer::Impl::bindProbeTextures() {
  gl.BindTextureUnit(1, probes.latticeTexture);
  gl.BindTextureUnit(2, probes.staticTexture);
  gl.BindTextureUnit(3, probes.radianceTexture);
}

void Renderer::Impl::drawReceivers(const Frame& frame, const FramePlan& plan) {
  if (!plan.flat) bindProbeTextures();
  drawOpaqueList(receivers, receiverPrograms[size_t(frame.probeLookup)], true, plan.receiverExtra, frame, plan);
}

// BLEND and transmissive instances last, over the opaque ones and the background: "over"
// blending (src·α + dst·(1 − α)), depth tested against the opaque depth but not written, back to
// front by the view depth of each instance's bounding-box centre (a receiver's as it moves):
// exact for layers that do not interleave, approximate where two overlap in depth (no
// per-triangle sort).
void Renderer::Impl::drawBlended(const Frame& frame, const FramePlan& plan) {
  struct Layer {
    const Instance* in;
    bool receiver;
    double depth;
  };
  std::vector<Layer> layers;
  const glm::dvec3 eye(frame.camera.cameraToWorld[3]), forward(-glm::dvec3(frame.camera.cameraToWorld[2]));
  for (const Instance& in : instances)
    if (in.blend) layers.push_back({&in, false, glm::dot(0.5 * (in.restLo + in.restHi) - eye, forward)});
  if (plan.drawReceivers)
    for (const Instance& in : receivers) {
      if (!in.blend) continue;
      const glm::dvec3 c = glm::dvec3(instanceMotion(animation, in.placement, frame.time) *
                                      glm::dvec4(0.5 * (in.restLo + in.restHi), 1.0));
      layers.push_back({&in, true, glm::dot(c - eye, forward)});
    }
  std::stable_sort(layers.begin(), layers.end(), [](const Layer& a, const Layer& b) { return a.depth > b.depth; });
  gl.Enable(GL_BLEND);
  gl.BlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  gl.DepthMask(GL_FALSE);
  if (plan.drawReceivers) bindProbeTextures();
  for (const Layer& layer : layers) {
    const Instance& in = *layer.in;
    const Program& p = layer.receiver ? receiverProgram(frame.probeLookup, variantOf(in, plan.receiverExtra))
                                      : bakedProgram(variantOf(in, plan.bakedExtra));
    gl.UseProgram(p.id);
    gl.ProgramUniformMatrix4fv(p.id, p.viewProj, 1, GL_FALSE, &plan.viewProj[0][0]);
    const bool mirrored = layer.receiver ? placeReceiver(p, in, frame, false) : placeBaked(in, plan);
    drawInstance(p, in, mirrored, false);
  }
  gl.DepthMask(GL_TRUE);
  gl.Disable(GL_BLEND);
}

ImageRgb Renderer::Impl::readBack(int width, int height) {
  const auto t2 = std::chrono::steady_clock::now();
  readback.resize(size_t(width) * height);
  if (target.resolveFramebuffer) {
    // The average of each pixel's samples (a box filter over the pixel).
    gl.BlitNamedFramebuffer(target.framebuffer, target.resolveFramebuffer, 0, 0, width, height, 0, 0, width, height,
                            GL_COLOR_BUFFER_BIT, GL_NEAREST);
    gl.BindFramebuffer(GL_FRAMEBUFFER, target.resolveFramebuffer);
  }
  gl.PixelStorei(GL_PACK_ALIGNMENT, 4);
  gl.ReadPixels(0, 0, width, height, GL_RGBA, GL_FLOAT, readback.data());
  checkError("reading the frame back");
  gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
  ImageRgb image(width, height);
  for (int y = 0; y < height; ++y) {  // GL's row 0 is the bottom
    const glm::vec4* src = readback.data() + size_t(height - 1 - y) * width;
    for (int x = 0; x < width; ++x) image.at(x, y) = glm::vec3(src[x]);
  }
  stats.readbackMs = msSince(t2);
  return image;
}

int Renderer::bands() const { return impl_->bands; }
bool Renderer::bakedDirectPart() const { return impl_->bakedDirect; }
size_t Renderer::receiverCount() const { return impl_->receivers.size(); }
const FrameStats& Renderer::lastFrame() const { return impl_->stats; }

std::vector<std::string> Renderer::warnings() const {
  std::vector<std::string> out = impl_->warnings;
  const auto& rs = impl_->receivers;
  if (impl_->grid == nullptr && !rs.empty()) {
    std::string names;
    for (size_t i = 0; i < std::min<size_t>(rs.size(), 3); ++i)
      names += cat(i ? ", '" : "'", rs[i].placement.name, "'");
    if (rs.size() > 3) names += cat(" and ", rs.size() - 3, " more");
    out.push_back(cat(rs.size(), " receiver instance", rs.size() > 1 ? "s" : "", " (", names,
                      ") not drawn: receivers are lit from a probe grid and none was given"));
  }
  return out;
}

}  // namespace prt::render
