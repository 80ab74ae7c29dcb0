// Move-only owners of GL objects (private header of render/), after Filament's
// backend/src/opengl (GLBufferObject, GLTexture, OpenGLProgram: one GL name per handle). Each
// holds its name and the function table of the context that made it, and deletes the name when
// it goes: the only place in render/ where GL objects are deleted. Destroy them with that context
// current (Renderer's destructor makes it so).
#pragma once

#include <utility>

#include "gl_functions.h"

namespace prt::render {

enum class GlKind { Buffer, Texture, Renderbuffer, Framebuffer, VertexArray, Shader, Program };

template <GlKind kind>
class GlObject {
 public:
  GlObject() = default;
  /// Takes ownership of `name` (0: none), made with `gl`.
  GlObject(const GlFunctions& gl, GLuint name) : gl_(&gl), name_(name) {}
  GlObject(const GlObject&) = delete;
  GlObject& operator=(const GlObject&) = delete;
  GlObject(GlObject&& other) noexcept : gl_(other.gl_), name_(std::exchange(other.name_, 0)) {}
  GlObject& operator=(GlObject&& other) noexcept {
    if (this != &other) {
      reset();
      gl_ = other.gl_;
      name_ = std::exchange(other.name_, 0);
    }
    return *this;
  }
  ~GlObject() { reset(); }

  /// The GL name, 0 for none. It converts implicitly, so that the object goes where GL takes a
  /// name (the name stays owned here).
  GLuint name() const { return name_; }
  operator GLuint() const { return name_; }

  /// Deletes the object now; the name becomes 0.
  void reset() {
    if (name_ == 0) return;
    if constexpr (kind == GlKind::Buffer) gl_->DeleteBuffers(1, &name_);
    if constexpr (kind == GlKind::Texture) gl_->DeleteTextures(1, &name_);
    if constexpr (kind == GlKind::Renderbuffer) gl_->DeleteRenderbuffers(1, &name_);
    if constexpr (kind == GlKind::Framebuffer) gl_->DeleteFramebuffers(1, &name_);
    if constexpr (kind == GlKind::VertexArray) gl_->DeleteVertexArrays(1, &name_);
    if constexpr (kind == GlKind::Shader) gl_->DeleteShader(name_);
    if constexpr (kind == GlKind::Program) gl_->DeleteProgram(name_);
    name_ = 0;
  }

 private:
  const GlFunctions* gl_ = nullptr;
  GLuint name_ = 0;
};

using GlBuffer = GlObject<GlKind::Buffer>;
using GlTexture = GlObject<GlKind::Texture>;
using GlRenderbuffer = GlObject<GlKind::Renderbuffer>;
using GlFramebuffer = GlObject<GlKind::Framebuffer>;
using GlVertexArray = GlObject<GlKind::VertexArray>;
using GlShader = GlObject<GlKind::Shader>;
using GlProgram = GlObject<GlKind::Program>;

/// New objects (the GL 4.5 glCreate* calls: the object exists at once, no bind needed).
inline GlBuffer createBuffer(const GlFunctions& gl) {
  GLuint name = 0;
  gl.CreateBuffers(1, &name);
  return GlBuffer(gl, name);
}
inline GlTexture createTexture(const GlFunctions& gl, GLenum target) {
  GLuint name = 0;
  gl.CreateTextures(target, 1, &name);
  return GlTexture(gl, name);
}
inline GlRenderbuffer createRenderbuffer(const GlFunctions& gl) {
  GLuint name = 0;
  gl.CreateRenderbuffers(1, &name);
  return GlRenderbuffer(gl, name);
}
inline GlFramebuffer createFramebuffer(const GlFunctions& gl) {
  GLuint name = 0;
  gl.CreateFramebuffers(1, &name);
  return GlFramebuffer(gl, name);
}
inline GlVertexArray createVertexArray(const GlFunctions& gl) {
  GLuint name = 0;
  gl.CreateVertexArrays(1, &name);
  return GlVertexArray(gl, name);
}
inline GlShader createShader(const GlFunctions& gl, GLenum type) { return GlShader(gl, gl.CreateShader(type)); }
inline GlProgram createProgram(const GlFunctions& gl) { return GlProgram(gl, gl.CreateProgram()); }

}  // namespace prt::render
