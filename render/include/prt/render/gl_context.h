// Headless OpenGL 4.5 core contexts through OSMesa or EGL, from one binary.
//
// Both back ends run Mesa's llvmpipe on the machines prt is developed on; EGL can also reach a
// real GPU through EGL_EXT_platform_device. No window system is involved: a context draws into
// framebuffer objects only. The binary links libEGL and opens libOSMesa at run time, never
// libGL/libOpenGL, and
// every GL entry point is loaded from the current context (docs/render.md says why).
#pragma once

#include <memory>
#include <string>

namespace prt::render {

enum class GlBackend { OSMesa, Egl };

/// Parses "osmesa" or "egl"; throws prt::Error naming the accepted values otherwise.
GlBackend parseGlBackend(const std::string& name);
/// "osmesa" or "egl".
const char* glBackendName(GlBackend backend);

/// Which EGL platform to open (ignored by OSMesa).
enum class EglPlatform {
  Auto,         // the device platform if a hardware (non-software) EGL device exists, else surfaceless
  Device,       // EGL_EXT_platform_device only (the first hardware device, else the software one)
  Surfaceless,  // EGL_MESA_platform_surfaceless only
};

struct GlContextOptions {
  EglPlatform eglPlatform = EglPlatform::Auto;
};

struct GlFunctions;  // the loaded function table (render/src/gl_functions.h)

/// One OpenGL 4.5 core context, current on the creating thread after construction.
/// Several contexts, of either back end, may exist in one process; call makeCurrent() before
/// using one after another was made current. Not thread-safe: use a context on one thread.
class GlContext {
 public:
  /// Opens a context. `width` × `height` is the default frame size for renderers on it.
  /// Throws prt::Error with one line on failure, e.g. "EGL: no display on the surfaceless
  /// platform (eglInitialize: EGL_NOT_INITIALIZED)" or "OSMesa: no OpenGL 4.5 core context".
  GlContext(GlBackend backend, int width, int height, const GlContextOptions& options = {});
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  /// Makes this context current on the calling thread.
  void makeCurrent();

  GlBackend backend() const;
  int width() const;
  int height() const;
  /// How the context was reached: "OSMesa", "EGL surfaceless", "EGL device (/dev/dri/renderD128)".
  const std::string& platform() const;
  /// GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
  const std::string& renderer() const;
  /// GL_VERSION, e.g. "4.5 (Core Profile) Mesa 22.3.6".
  const std::string& version() const;
  /// GL_MAX_SAMPLES: the most samples per pixel a multisampled frame may have (4 on llvmpipe).
  int maxSamples() const;
  /// One line for summaries: "egl: EGL surfaceless, llvmpipe (...), 4.5 (Core Profile) Mesa ...".
  std::string description() const;

  /// The entry points loaded from this context (render library internals only).
  const GlFunctions& gl() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace prt::render
