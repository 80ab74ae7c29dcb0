// The one file that talks to OSMesa and EGL.
#include "prt/render/gl_context.h"

#include <dlfcn.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <mutex>
#include <type_traits>
#include <vector>

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include "gl_functions.h"
// osmesa.h pulls in the legacy <GL/gl.h>, whose GL 1.1 prototypes would make <GL/glcorearb.h>
// skip its 1.1 function pointer typedefs (PFNGLDRAWELEMENTSPROC, ...). glcorearb.h already
// defines every type osmesa.h needs, so gl.h is kept out by its include guard.
#define __gl_h_
#define GLAPIENTRY APIENTRY
#include <GL/osmesa.h>

#include "prt/error.h"

namespace prt::render {

GlBackend parseGlBackend(const std::string& name) {
  if (name == "osmesa") return GlBackend::OSMesa;
  if (name == "egl") return GlBackend::Egl;
  throw Error(cat("unknown GL back end '", name, "' (expected osmesa or egl)"));
}

const char* glBackendName(GlBackend backend) { return backend == GlBackend::OSMesa ? "osmesa" : "egl"; }

std::string glErrorName(GLenum error) {
  switch (error) {
    case GL_NO_ERROR:
      return "GL_NO_ERROR";
    case GL_INVALID_ENUM:
      return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE:
      return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION:
      return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION:
      return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY:
      return "GL_OUT_OF_MEMORY";
    default: {
      char buf[16];
      std::snprintf(buf, sizeof buf, "0x%04x", error);
      return buf;
    }
  }
}

void GlFunctions::load(void* (*getProcAddress)(const char*), const char* who) {
#define PRT_GL_LOAD(type, name)                              \
  name = reinterpret_cast<type>(getProcAddress("gl" #name)); \
  if (!name) throw Error(cat(who, ": GL entry point gl" #name " not found"));
  PRT_GL_FUNCTIONS(PRT_GL_LOAD)
#undef PRT_GL_LOAD
}

namespace {

constexpr int kMajor = 4, kMinor = 5;

const char* eglErrorName(EGLint e) {
  switch (e) {
    case EGL_SUCCESS:
      return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED:
      return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS:
      return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC:
      return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE:
      return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG:
      return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT:
      return "EGL_BAD_CONTEXT";
    case EGL_BAD_CURRENT_SURFACE:
      return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY:
      return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH:
      return "EGL_BAD_MATCH";
    case EGL_BAD_NATIVE_PIXMAP:
      return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW:
      return "EGL_BAD_NATIVE_WINDOW";
    case EGL_BAD_PARAMETER:
      return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE:
      return "EGL_BAD_SURFACE";
    case EGL_CONTEXT_LOST:
      return "EGL_CONTEXT_LOST";
    default:
      return "unknown EGL error";
  }
}

bool hasExtension(const char* list, const char* name) {
  if (!list) return false;
  const size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

// OSMesa is opened at run time, by the first OSMesa context. libOSMesa pulls in LLVM (llvmpipe):
// linked, its relocations cost every prt process ~55 ms at start, whether it renders or not
// (`prt --version` took 0.14 s, 0.06–0.07 s without it). EGL (glvnd's libEGL) is cheap and stays linked.
struct OsMesaApi {
  decltype(&::OSMesaCreateContextAttribs) createContextAttribs = nullptr;
  decltype(&::OSMesaGetProcAddress) getProcAddress = nullptr;
  decltype(&::OSMesaMakeCurrent) makeCurrent = nullptr;
  decltype(&::OSMesaDestroyContext) destroyContext = nullptr;
};

constexpr const char* kOsMesaLibrary = "libOSMesa.so.8";  // Mesa's soname since 2015

const OsMesaApi& osmesaApi() {
  static const OsMesaApi api = [] {  // a throw leaves it uninitialised: the next call tries again
    void* lib = dlopen(kOsMesaLibrary, RTLD_NOW | RTLD_LOCAL);
    if (!lib) throw Error(cat("OSMesa: cannot load ", kOsMesaLibrary, " (", dlerror(), ")"));
    OsMesaApi a;
    const auto load = [&](auto& fn, const char* name) {
      fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(dlsym(lib, name));
      if (!fn) throw Error(cat("OSMesa: ", kOsMesaLibrary, " has no ", name));
    };
    load(a.createContextAttribs, "OSMesaCreateContextAttribs");
    load(a.getProcAddress, "OSMesaGetProcAddress");
    load(a.makeCurrent, "OSMesaMakeCurrent");
    load(a.destroyContext, "OSMesaDestroyContext");
    return a;  // the library stays loaded for the process
  }();
  return api;
}

template <class F>
F eglProc(const char* name) {
  return reinterpret_cast<F>(eglGetProcAddress(name));
}

// eglTerminate tears down every context of a display, and eglGetPlatformDisplayEXT hands out
// the same EGLDisplay for the same arguments: count the users so that closing one GlContext
// does not kill another on the same display.
std::mutex gDisplayMutex;
std::map<EGLDisplay, int> gDisplayUsers;

void retainDisplay(EGLDisplay d) {
  std::lock_guard lock(gDisplayMutex);
  ++gDisplayUsers[d];
}

void releaseDisplay(EGLDisplay d) {
  std::lock_guard lock(gDisplayMutex);
  if (--gDisplayUsers[d] == 0) {
    gDisplayUsers.erase(d);
    eglTerminate(d);
  }
}

}  // namespace

struct GlContext::Impl {
  GlBackend backend = GlBackend::OSMesa;
  int width = 0, height = 0;
  std::string platform, renderer, version;
  GlFunctions gl;

  // OSMesa: the context and the small client colour buffer OSMesaMakeCurrent insists on,
  // although everything is drawn into FBOs.
  OSMesaContext osmesa = nullptr;
  std::vector<unsigned char> osmesaBuffer = std::vector<unsigned char>(4 * 4 * 4);

  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;

  void openOSMesa();
  void openEgl(EglPlatform platform);
  // Initializes `d` and creates the context; returns "" or why it failed (display released).
  std::string tryEglDisplay(EGLDisplay d, const std::string& where);
  void makeCurrent();
  void queryAndCheck(const char* who);
  void close();
};

void GlContext::Impl::openOSMesa() {
  const int attribs[] = {OSMESA_FORMAT,
                         OSMESA_RGBA,
                         OSMESA_DEPTH_BITS,
                         0,
                         OSMESA_PROFILE,
                         OSMESA_CORE_PROFILE,
                         OSMESA_CONTEXT_MAJOR_VERSION,
                         kMajor,
                         OSMESA_CONTEXT_MINOR_VERSION,
                         kMinor,
                         0};
  osmesa = osmesaApi().createContextAttribs(attribs, nullptr);
  if (!osmesa) throw Error(cat("OSMesa: no OpenGL ", kMajor, ".", kMinor, " core context"));
  platform = "OSMesa";
  makeCurrent();
  gl.load([](const char* name) { return reinterpret_cast<void*>(osmesaApi().getProcAddress(name)); }, "OSMesa");
  queryAndCheck("OSMesa");
}

std::string GlContext::Impl::tryEglDisplay(EGLDisplay d, const std::string& where) {
  if (d == EGL_NO_DISPLAY) return cat("no display on the ", where, " (", eglErrorName(eglGetError()), ")");
  EGLint major = 0, minor = 0;
  if (!eglInitialize(d, &major, &minor))
    return cat("no display on the ", where, " (eglInitialize: ", eglErrorName(eglGetError()), ")");
  retainDisplay(d);
  auto fail = [&](const std::string& why) {
    releaseDisplay(d);
    return cat(where, ": ", why);
  };
  if (!eglBindAPI(EGL_OPENGL_API)) return fail("eglBindAPI(EGL_OPENGL_API) failed");
  const char* ext = eglQueryString(d, EGL_EXTENSIONS);
  if (!hasExtension(ext, "EGL_KHR_surfaceless_context")) return fail("EGL_KHR_surfaceless_context missing");

  // Without a surface the config only matters for its absence: take EGL_NO_CONFIG_KHR where the
  // display allows it, else any config that can render OpenGL.
  EGLConfig config = EGL_NO_CONFIG_KHR;
  if (!hasExtension(ext, "EGL_KHR_no_config_context")) {
    const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint n = 0;
    if (!eglChooseConfig(d, want, &config, 1, &n) || n < 1)
      return fail("no config for OpenGL and no EGL_KHR_no_config_context");
  }
  const EGLint attribs[] = {
      EGL_CONTEXT_MAJOR_VERSION,           kMajor,  EGL_CONTEXT_MINOR_VERSION, kMinor, EGL_CONTEXT_OPENGL_PROFILE_MASK,
      EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  EGLContext c = eglCreateContext(d, config, EGL_NO_CONTEXT, attribs);
  if (c == EGL_NO_CONTEXT)
    return fail(cat("no OpenGL ", kMajor, ".", kMinor, " core context (", eglErrorName(eglGetError()), ")"));
  display = d;
  context = c;
  return "";
}

void GlContext::Impl::openEgl(EglPlatform want) {
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  auto getPlatformDisplay = eglProc<PFNEGLGETPLATFORMDISPLAYEXTPROC>("eglGetPlatformDisplayEXT");
  if (!getPlatformDisplay || !hasExtension(client, "EGL_EXT_platform_base"))
    throw Error("EGL: no display (no EGL_EXT_platform_base: is an EGL vendor such as libegl-mesa0 installed?)");

  std::vector<std::string> failures;

  // Device platform: a hardware device if there is one; the software device only when asked.
  if (want != EglPlatform::Surfaceless && hasExtension(client, "EGL_EXT_platform_device")) {
    auto queryDevices = eglProc<PFNEGLQUERYDEVICESEXTPROC>("eglQueryDevicesEXT");
    auto queryDeviceString = eglProc<PFNEGLQUERYDEVICESTRINGEXTPROC>("eglQueryDeviceStringEXT");
    EGLint count = 0;
    std::vector<EGLDeviceEXT> devices;
    if (queryDevices && queryDeviceString && queryDevices(0, nullptr, &count) && count > 0) {
      devices.resize(size_t(count));
      queryDevices(count, devices.data(), &count);
      devices.resize(size_t(count));
    }
    EGLDeviceEXT chosen = nullptr;
    std::string name;
    for (int pass = 0; pass < 2 && !chosen; ++pass) {
      for (EGLDeviceEXT dev : devices) {
        const char* devExt = queryDeviceString(dev, EGL_EXTENSIONS);
        const bool software = hasExtension(devExt, "EGL_MESA_device_software");
        if (software != (pass == 1)) continue;
        if (software && want != EglPlatform::Device) continue;
        chosen = dev;
        const char* file = nullptr;
        if (hasExtension(devExt, "EGL_EXT_device_drm_render_node"))
          file = queryDeviceString(dev, EGL_DRM_RENDER_NODE_FILE_EXT);
        if (!file && hasExtension(devExt, "EGL_EXT_device_drm")) file = queryDeviceString(dev, EGL_DRM_DEVICE_FILE_EXT);
        name = file ? file : software ? "software" : "hardware";
        break;
      }
    }
    if (chosen) {
      std::string why = tryEglDisplay(getPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, chosen, nullptr),
                                      cat("device platform (", name, ")"));
      if (why.empty()) {
        platform = cat("EGL device (", name, ")");
      } else {
        failures.push_back(why);
      }
    } else if (want == EglPlatform::Device) {
      failures.push_back("no EGL device on the device platform");
    }
  } else if (want == EglPlatform::Device) {
    failures.push_back("no device platform (EGL_EXT_platform_device missing)");
  }

  if (context == EGL_NO_CONTEXT && want != EglPlatform::Device) {
    if (!hasExtension(client, "EGL_MESA_platform_surfaceless")) {
      failures.push_back("no display on the surfaceless platform (EGL_MESA_platform_surfaceless missing)");
    } else {
      std::string why = tryEglDisplay(getPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr),
                                      "surfaceless platform");
      if (why.empty())
        platform = "EGL surfaceless";
      else
        failures.push_back(why);
    }
  }
  if (context == EGL_NO_CONTEXT) {
    std::string msg = "EGL:";
    for (size_t i = 0; i < failures.size(); ++i) msg += (i ? "; " : " ") + failures[i];
    throw Error(msg);
  }
  makeCurrent();
  gl.load([](const char* name) { return reinterpret_cast<void*>(eglGetProcAddress(name)); }, "EGL");
  queryAndCheck("EGL");
}

void GlContext::Impl::makeCurrent() {
  if (backend == GlBackend::OSMesa) {
    if (!osmesaApi().makeCurrent(osmesa, osmesaBuffer.data(), GL_UNSIGNED_BYTE, 4, 4))
      throw Error("OSMesa: OSMesaMakeCurrent failed");
  } else {
    if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context))
      throw Error(cat("EGL: eglMakeCurrent failed (", eglErrorName(eglGetError()), ")"));
  }
}

void GlContext::Impl::queryAndCheck(const char* who) {
  auto str = [&](GLenum e) {
    const GLubyte* s = gl.GetString(e);
    return s ? std::string(reinterpret_cast<const char*>(s)) : std::string();
  };
  renderer = str(GL_RENDERER);
  version = str(GL_VERSION);
  GLint major = 0, minor = 0, profile = 0;
  gl.GetIntegerv(GL_MAJOR_VERSION, &major);
  gl.GetIntegerv(GL_MINOR_VERSION, &minor);
  gl.GetIntegerv(GL_CONTEXT_PROFILE_MASK, &profile);
  // An empty renderer string is the symptom of GL calls going to the wrong library.
  if (renderer.empty() || major * 10 + minor < kMajor * 10 + kMinor || !(profile & GL_CONTEXT_CORE_PROFILE_BIT))
    throw Error(cat(who, ": context is not OpenGL ", kMajor, ".", kMinor, " core (GL_VERSION '", version,
                    "', GL_RENDERER '", renderer, "')"));
}

void GlContext::Impl::close() {
  if (osmesa) {
    osmesaApi().destroyContext(osmesa);
    osmesa = nullptr;
  }
  if (context != EGL_NO_CONTEXT) {
    // Release only our own context: another (possibly OSMesa) context may be current now.
    if (eglGetCurrentContext() == context) eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display, context);
    context = EGL_NO_CONTEXT;
    releaseDisplay(display);
    display = EGL_NO_DISPLAY;
  }
}

GlContext::GlContext(GlBackend backend, int width, int height, const GlContextOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (width <= 0 || height <= 0) throw Error(cat("GL: bad frame size ", width, "x", height));
  impl_->backend = backend;
  impl_->width = width;
  impl_->height = height;
  try {
    if (backend == GlBackend::OSMesa)
      impl_->openOSMesa();
    else
      impl_->openEgl(options.eglPlatform);
  } catch (...) {
    impl_->close();
    throw;
  }
}

GlContext::~GlContext() { impl_->close(); }

void GlContext::makeCurrent() { impl_->makeCurrent(); }
GlBackend GlContext::backend() const { return impl_->backend; }
int GlContext::width() const { return impl_->width; }
int GlContext::height() const { return impl_->height; }
const std::string& GlContext::platform() const { return impl_->platform; }
const std::string& GlContext::renderer() const { return impl_->renderer; }
const std::string& GlContext::version() const { return impl_->version; }
const GlFunctions& GlContext::gl() const { return impl_->gl; }

int GlContext::maxSamples() const {
  GLint n = 0;
  impl_->gl.GetIntegerv(GL_MAX_SAMPLES, &n);
  return std::max(n, 1);
}

std::string GlContext::description() const {
  return cat(glBackendName(impl_->backend), ": ", impl_->platform, ", ", impl_->renderer, ", ", impl_->version);
}

}  // namespace prt::render
