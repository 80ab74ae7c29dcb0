// The screen-space reflection pass (Frame::screenReflections; docs/render.md, "Materials"). The
// opaque pixels write, besides their radiance, what their lobe weighs, what it reflected, where
// it points, and their radiance as the bake's transport re-emits it (reflection_inputs.glsl,
// attachments 1–4); after the opaque instances and the background the last is copied into a
// mipmapped texture, and a full-screen triangle marches each glossy pixel's mirror direction
// through the depth buffer and, where it meets a surface, puts W · L_hit in place of what the
// lobe reflected (shaders/reflection_fragment.glsl). Blended instances are drawn after it,
// neither reflected nor reflecting.
#include <algorithm>
#include <cmath>

#include <glm/gtc/matrix_inverse.hpp>

#include "camera.h"
#include "renderer_impl.h"
#include "shader_sources.h"

namespace prt::render {

namespace {

// Samples along the mirror direction's segment on the screen, at most: one a pixel on short
// segments, and the bisection finds the crossing between two samples on long ones.
constexpr int kReflectionSteps = 32;

GlTexture targetTexture(const GlFunctions& gl, GLenum format, int width, int height, int levels) {
  GlTexture t = createTexture(gl, GL_TEXTURE_2D);
  gl.TextureStorage2D(t, levels, format, width, height);
  gl.TextureParameteri(t, GL_TEXTURE_MIN_FILTER, levels > 1 ? GL_LINEAR_MIPMAP_LINEAR : GL_NEAREST);
  gl.TextureParameteri(t, GL_TEXTURE_MAG_FILTER, levels > 1 ? GL_LINEAR : GL_NEAREST);
  gl.TextureParameteri(t, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  gl.TextureParameteri(t, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  return t;
}

}  // namespace

void Renderer::Impl::attachReflectionTargets(Target& t) {
  const int w = t.width, h = t.height;
  t.reflections = true;
  t.depthTexture = targetTexture(gl, GL_DEPTH_COMPONENT32F, w, h, 1);
  gl.NamedFramebufferTexture(t.framebuffer, GL_DEPTH_ATTACHMENT, t.depthTexture, 0);
  for (size_t i = 0; i < t.reflectionInputs.size(); ++i) {
    t.reflectionInputs[i] = targetTexture(gl, GL_RGBA16F, w, h, 1);
    gl.NamedFramebufferTexture(t.framebuffer, GLenum(GL_COLOR_ATTACHMENT1 + i), t.reflectionInputs[i], 0);
  }
  const int levels = 1 + int(std::floor(std::log2(double(std::max(w, h)))));
  t.radianceCopy = targetTexture(gl, GL_RGBA16F, w, h, levels);
  t.copyFramebuffer = createFramebuffer(gl);
  gl.NamedFramebufferTexture(t.copyFramebuffer, GL_COLOR_ATTACHMENT0, t.radianceCopy, 0);
  t.reflectionFramebuffer = createFramebuffer(gl);
  gl.NamedFramebufferRenderbuffer(t.reflectionFramebuffer, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, t.color);
  for (GLuint fb : {GLuint(t.copyFramebuffer), GLuint(t.reflectionFramebuffer)}) {
    gl.NamedFramebufferDrawBuffer(fb, GL_COLOR_ATTACHMENT0);
    if (gl.CheckNamedFramebufferStatus(fb, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw Error("GL: the screen-space reflections' framebuffer is incomplete");
  }
}

void Renderer::Impl::drawReflectionInputs(bool on) {
  const GLuint fb = target.framebuffer;
  if (!on) {
    gl.NamedFramebufferDrawBuffer(fb, GL_COLOR_ATTACHMENT0);
    return;
  }
  const GLenum buffers[5] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2, GL_COLOR_ATTACHMENT3,
                             GL_COLOR_ATTACHMENT4};
  gl.NamedFramebufferDrawBuffers(fb, 5, buffers);
  const float zero[4] = {0, 0, 0, 0};
  for (GLint i = 1; i < 5; ++i) gl.ClearNamedFramebufferfv(fb, GL_COLOR, i, zero);
}

void Renderer::Impl::drawReflections(const Frame& frame, const FramePlan& plan) {
  if (!reflection.id) {
    Program p = linkProgram(gl, backgroundVertexShader(), reflectionFragmentShader(), "screen-space reflections");
    reflection.id = std::move(p.id);
    auto loc = [&](const char* name) { return gl.GetUniformLocation(reflection.id, name); };
    reflection.viewProj = loc("uViewProj");
    reflection.invViewProj = loc("uInvViewProj");
    reflection.viewport = loc("uViewport");
    reflection.maxDistance = loc("uMaxDistance");
    reflection.perspective = loc("uPerspective");
    reflection.pixelsPerUnit = loc("uPixelsPerUnit");
    reflection.steps = loc("uSteps");
  }
  if (!background.emptyVao) background.emptyVao = createVertexArray(gl);
  const Target& t = target;
  const int w = plan.width, h = plan.height;
  // The opaque surfaces' bounced radiance, and its mip levels: the lobe's footprint at a hit
  // picks its level.
  gl.NamedFramebufferReadBuffer(t.framebuffer, GL_COLOR_ATTACHMENT4);
  gl.BlitNamedFramebuffer(t.framebuffer, t.copyFramebuffer, 0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
  gl.NamedFramebufferReadBuffer(t.framebuffer, GL_COLOR_ATTACHMENT0);
  gl.GenerateTextureMipmap(t.radianceCopy);

  const GLuint id = reflection.id;
  const glm::mat4 inverse(glm::inverse(glm::dmat4(plan.viewProj)));
  const glm::vec2 viewport{float(w), float(h)};
  const double diagonal = glm::length(glm::dvec3(boundsMax) - glm::dvec3(boundsMin));
  const glm::dmat4 proj = projection(frame.camera, double(w) / h, 1.0);
  gl.ProgramUniformMatrix4fv(id, reflection.viewProj, 1, GL_FALSE, &plan.viewProj[0][0]);
  gl.ProgramUniformMatrix4fv(id, reflection.invViewProj, 1, GL_FALSE, &inverse[0][0]);
  gl.ProgramUniform2fv(id, reflection.viewport, 1, &viewport.x);
  gl.ProgramUniform1f(id, reflection.maxDistance, float(std::max(diagonal, 1e-3)));
  gl.ProgramUniform1f(id, reflection.perspective, frame.camera.perspective ? 1.0f : 0.0f);
  gl.ProgramUniform1f(id, reflection.pixelsPerUnit, float(0.5 * h * proj[1][1]));
  gl.ProgramUniform1i(id, reflection.steps, kReflectionSteps);
  gl.BindTextureUnit(0, t.depthTexture);
  for (GLuint i = 0; i < 3; ++i) gl.BindTextureUnit(1 + i, t.reflectionInputs[i]);  // the fourth is copied
  gl.BindTextureUnit(4, t.radianceCopy);

  gl.BindFramebuffer(GL_FRAMEBUFFER, t.reflectionFramebuffer);
  gl.Disable(GL_DEPTH_TEST);
  gl.Enable(GL_BLEND);
  gl.BlendFuncSeparate(GL_ONE, GL_ONE, GL_ZERO, GL_ONE);  // radiance added, alpha kept
  gl.UseProgram(id);
  gl.BindVertexArray(background.emptyVao);
  gl.DrawArrays(GL_TRIANGLES, 0, 3);
  gl.Disable(GL_BLEND);
  gl.BlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  gl.Enable(GL_DEPTH_TEST);
  gl.BindFramebuffer(GL_FRAMEBUFFER, t.framebuffer);
  checkError("screen-space reflections");
}

}  // namespace prt::render
