// The background pass: a full-screen triangle at the far depth, drawn after the opaque instances
// (before the blended ones) with GL_EQUAL so that only pixels no opaque instance covered run it.
// Each pixel's centre ray (the same as the orbit and glTF cameras' rays, docs/render.md) looks
// up RigBackground::radiance (shaders/background_fragment.glsl).
#include <cmath>

#include "prt/error.h"
#include "renderer_impl.h"
#include "shader_sources.h"

namespace prt::render {

void checkBackgroundSize(const std::string& what, size_t maps, size_t caps) {
  if (maps > size_t(kMaxBackgroundMaps))
    throw Error(cat(what, ": ", maps, " environment maps, at most ", kMaxBackgroundMaps, " can be drawn"));
  if (caps > size_t(kMaxBackgroundCaps))
    throw Error(cat(what, ": ", caps, " suns and disks, at most ", kMaxBackgroundCaps, " can be drawn"));
}

GLuint Renderer::Impl::environmentTexture(const std::shared_ptr<const ImageRgb>& image) {
  auto it = background.envTextures.find(image.get());
  if (it != background.envTextures.end()) return it->second.second;
  GLint maxSize = 0;
  gl.GetIntegerv(GL_MAX_TEXTURE_SIZE, &maxSize);
  if (image->width < 1 || image->height < 1 || image->width > maxSize || image->height > maxSize)
    throw Error(cat("background: environment map of ", image->width, "x", image->height,
                    " pixels exceeds the GL's texture size limit of ", maxSize));
  // Row 0 (v near 0, towards +Y) at t = 0, repeating in u, clamped in v: texture(u, v) is
  // sampleEquirect's bilinear lookup.
  GlTexture tex = linearFloatTexture(GL_RGB32F, GL_RGB, image->width, image->height, image->pixels.data(), GL_REPEAT,
                                     GL_CLAMP_TO_EDGE);
  checkError("uploading an environment map for the background");
  const GLuint name = tex;
  background.envTextures.emplace(image.get(), std::make_pair(image, std::move(tex)));
  return name;
}

// The background's program, its uniforms and the empty vertex array of its triangle.
void Renderer::Impl::linkBackground() {
  Program p = linkProgram(gl, backgroundVertexShader(), backgroundFragmentShader(), "background");
  Background& b = background;
  b.id = std::move(p.id);
  auto loc = [&](const char* name) { return gl.GetUniformLocation(b.id, name); };
  b.camera = loc("uCamera");
  b.tan = loc("uTan");
  b.ortho = loc("uOrtho");
  b.viewport = loc("uViewport");
  b.mapCount = loc("uMapCount");
  b.worldToMap = loc("uWorldToMap");
  b.mapScale = loc("uMapScale");
  b.capCount = loc("uCapCount");
  b.caps = loc("uCaps");
  b.capRadiance = loc("uCapRadiance");
  b.uniformRadiance = loc("uUniformRadiance");
  b.emptyVao = createVertexArray(gl);
}

void Renderer::Impl::drawBackground(const RigBackground& b, const CameraView& camera, int width, int height) {
  checkBackgroundSize("background", b.maps.size(), b.caps.size());
  if (!background.id) linkBackground();
  const Background& bg = background;
  const GLuint id = bg.id;
  const glm::mat3 rotation(glm::dmat3(camera.cameraToWorld));
  const double tanY = std::tan(0.5 * camera.yfov);
  const glm::vec2 tans(float(tanY * width / height), float(tanY));
  const glm::vec2 viewport{float(width), float(height)};
  gl.ProgramUniformMatrix3fv(id, bg.camera, 1, GL_FALSE, &rotation[0][0]);
  gl.ProgramUniform2fv(id, bg.tan, 1, &tans.x);
  gl.ProgramUniform1i(id, bg.ortho, camera.perspective ? 0 : 1);
  gl.ProgramUniform2fv(id, bg.viewport, 1, &viewport.x);
  gl.ProgramUniform1i(id, bg.mapCount, GLint(b.maps.size()));
  for (size_t i = 0; i < b.maps.size(); ++i) {
    const glm::mat3 m(b.maps[i].worldToMap);
    const glm::vec3 scale(b.maps[i].scale);
    gl.ProgramUniformMatrix3fv(id, bg.worldToMap + GLint(i), 1, GL_FALSE, &m[0][0]);
    gl.ProgramUniform3fv(id, bg.mapScale + GLint(i), 1, &scale.x);
    gl.BindTextureUnit(GLuint(4 + i), environmentTexture(b.maps[i].image));
  }
  std::vector<glm::vec4> caps, capRadiance;
  for (const RigBackground::Cap& c : b.caps) {
    caps.emplace_back(glm::vec3(c.direction), float(c.cosRadius));
    capRadiance.emplace_back(glm::vec3(c.radiance), 0.0f);
  }
  gl.ProgramUniform1i(id, bg.capCount, GLint(caps.size()));
  if (!caps.empty()) {
    gl.ProgramUniform4fv(id, bg.caps, GLsizei(caps.size()), &caps[0].x);
    gl.ProgramUniform4fv(id, bg.capRadiance, GLsizei(caps.size()), &capRadiance[0].x);
  }
  const glm::vec3 uniform(b.uniform);
  gl.ProgramUniform3fv(id, bg.uniformRadiance, 1, &uniform.x);
  gl.UseProgram(id);
  gl.Disable(GL_CULL_FACE);
  gl.DepthFunc(GL_EQUAL);
  gl.BindVertexArray(bg.emptyVao);
  gl.DrawArrays(GL_TRIANGLES, 0, 3);
  gl.DepthFunc(GL_GREATER);
  checkError("drawing the background");
}

}  // namespace prt::render
