// Rasterizing baked instances with per-vertex SH transfer, and receivers lit per pixel from the
// probe grid (docs/render.md).
#include "prt/render/renderer.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <string>

#include "direct_shading.h"
#include "gl_functions.h"
#include "probe_shading.h"
#include "shader_sources.h"
#include "shader_variants.h"
#include "prt/animation.h"
#include "prt/error.h"

namespace prt::render {

namespace {

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

GLint wrapMode(int gltf) {
  // glTF stores the GL enums themselves.
  return gltf == GL_CLAMP_TO_EDGE || gltf == GL_MIRRORED_REPEAT ? gltf : GL_REPEAT;
}

// Reversed depth (near → 1, far → 0) with glClipControl(GL_ZERO_TO_ONE) and a float depth
// buffer: float precision then falls where depth values are small, which makes the precision
// nearly uniform in distance and allows an infinite far plane.
glm::dmat4 projection(const CameraView& c, double aspect, double orthoFar) {
  glm::dmat4 p(0.0);
  const double n = c.znear;
  if (c.perspective) {
    const double f = 1.0 / std::tan(0.5 * c.yfov);
    p[0][0] = f / aspect;
    p[1][1] = f;
    p[2][3] = -1.0;  // w_clip = -z_view
    if (c.zfar > 0.0) {
      // depth = (A z + B) / -z with depth(-n) = 1, depth(-far) = 0.
      p[2][2] = n / (c.zfar - n);
      p[3][2] = n * c.zfar / (c.zfar - n);
    } else {
      p[3][2] = n;  // depth = n / -z
    }
  } else {
    const double far = c.zfar > 0.0 ? c.zfar : orthoFar;
    p[0][0] = 1.0 / (c.ymag * aspect);
    p[1][1] = 1.0 / c.ymag;
    p[2][2] = 1.0 / (far - n);  // depth = (z + far) / (far - n): 1 at -n, 0 at -far
    p[3][2] = far / (far - n);
    p[3][3] = 1.0;
  }
  return p;
}

}  // namespace

CameraView cameraView(const Camera& camera) {
  CameraView v;
  v.cameraToWorld = camera.world;
  for (int i = 0; i < 3; ++i) {
    const glm::dvec3 axis(camera.world[i]);
    const double len = glm::length(axis);
    if (len > 0.0) v.cameraToWorld[i] = glm::dvec4(axis / len, 0.0);
  }
  v.perspective = camera.perspective;
  v.yfov = camera.yfov;
  v.ymag = camera.ymag;
  v.znear = camera.znear;
  v.zfar = camera.zfar;
  return v;
}

void orbitFraming(const Scene& scene, glm::dvec3& lo, glm::dvec3& hi) {
  lo = glm::dvec3(scene.boundsMin);
  hi = glm::dvec3(scene.boundsMax);
  size_t n = 0;
  for (const MeshInstance& m : scene.meshes) n += m.vertexCount();
  if (n < 100) return;  // too few for percentiles to mean anything
  // At most ~64k positions, taken evenly: percentiles need no more.
  const size_t stride = std::max<size_t>(1, n / 65536);
  std::array<std::vector<float>, 3> axis;
  size_t i = 0;
  for (const MeshInstance& m : scene.meshes)
    for (const glm::vec3& p : m.positions)
      if (i++ % stride == 0)
        for (int a = 0; a < 3; ++a) axis[size_t(a)].push_back(p[a]);
  glm::dvec3 tlo, thi;
  for (int a = 0; a < 3; ++a) {
    std::vector<float>& v = axis[size_t(a)];
    const size_t k0 = v.size() / 100, k1 = v.size() - 1 - v.size() / 100;
    std::nth_element(v.begin(), v.begin() + ptrdiff_t(k0), v.end());
    tlo[a] = v[k0];
    std::nth_element(v.begin(), v.begin() + ptrdiff_t(k1), v.end());
    thi[a] = v[k1];
  }
  if (glm::length(thi - tlo) < 0.5 * glm::length(hi - lo)) {
    lo = tlo;
    hi = thi;
  }
}

glm::dvec3 orbitTarget(const Scene& scene, const OrbitCamera& orbit) {
  if (orbit.target) return glm::dvec3(*orbit.target);
  glm::dvec3 lo, hi;
  orbitFraming(scene, lo, hi);
  return 0.5 * (lo + hi);
}

CameraView orbitView(const Scene& scene, const OrbitCamera& orbit, double aspect) {
  glm::dvec3 lo, hi;
  orbitFraming(scene, lo, hi);
  const glm::dvec3 target = orbitTarget(scene, orbit);
  double radius = 0.5 * glm::length(hi - lo);
  if (!(radius > 0.0)) radius = 1.0;
  CameraView v;
  v.yfov = glm::radians(orbit.yfovDegrees);
  double distance = orbit.distance;
  if (distance <= 0.0) {
    // The bounding sphere touches the narrower of the two fields of view.
    const double half = std::min(0.5 * v.yfov, std::atan(std::tan(0.5 * v.yfov) * aspect));
    distance = radius / std::sin(half);
  }
  const double az = glm::radians(orbit.azimuthDegrees);
  const double el = glm::radians(std::clamp(orbit.elevationDegrees, -89.0, 89.0));
  const glm::dvec3 back(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
  const glm::dvec3 right = glm::normalize(glm::cross(glm::dvec3(0, 1, 0), back));
  const glm::dvec3 up = glm::cross(back, right);
  v.cameraToWorld = glm::dmat4(glm::dvec4(right, 0), glm::dvec4(up, 0), glm::dvec4(back, 0),
                               glm::dvec4(target + distance * back, 1));
  v.znear = std::max(0.5 * (distance - radius), 1e-3 * radius);
  v.zfar = 0.0;
  return v;
}

struct Renderer::Impl {
  struct Instance {
    GLuint vao = 0;
    GLuint buffers[6] = {};  // positions, texcoords, colours, indices, transfer, normals
    GLuint backTransfer = 0;  // MeshInstance::transferBack (kVariantTwoSided), 0 if none
    GLuint directTransfer[2] = {};  // MeshInstance::transferDirect, transferDirectBack; 0 if none
    GLuint directBounce[2] = {};    // Frame::directBounce of this instance (front, back); with directTransfer
    size_t mesh = 0;                // its Scene::meshes entry
    size_t vertices = 0;
    bool bounceZero = true;         // directBounce holds zeros
    glm::dvec3 restLo{0.0}, restHi{0.0};  // bounds of the (rest-pose, for receivers) vertices
    GLsizei indexCount = 0;
    size_t triangles = 0;
    glm::vec4 baseColor{1.0f};
    GLuint texture = 0;
    GLuint transmissionTexture = 0;  // kVariantTransmission: bound to unit 6
    bool hasColor = false;
    bool doubleSided = false;
    float alphaCutoff = 0.5f, opacity = 1.0f;  // MASK's cutoff; 1 − transmissionFactor
    bool blend = false;  // drawn blended after the opaque pass (BLEND or transmission)
    int variant = 0;  // kVariantTexture | kVariantColor | ...: the shader variant it is drawn with
    MeshInstance placement;  // receivers: node and rest world only (no vertices), for the motion
  };
  struct Program {
    GLuint id = 0;
    GLint viewProj = -1, model = -1, normalMatrix = -1, light = -1, baseColor = -1, origin = -1, spacing = -1,
          dims = -1, nearZero = -1, alphaCutoff = -1, opacity = -1;
    // DIRECT variants (direct_shading.h)
    GLint directSh = -1, directCount = -1, directDir = -1, directIrradiance = -1, shadowed = -1, cascades = -1,
          cascadeFar = -1, viewOrigin = -1, viewForward = -1, shadowSize = -1, shadowMatrix = -1,
          shadowParams = -1, loopStep = -1;
  };

  GlContext& context;
  const GlFunctions& gl;
  int bands = 0;
  glm::vec3 boundsMin{0.0f}, boundsMax{0.0f};
  std::vector<Instance> instances;  // baked
  std::vector<Instance> receivers;
  SceneAnimation animation;         // moves the receivers
  std::vector<GLuint> textures;     // per Scene texture, 0 where unused
  // Per material variant (id 0: no instance needs it).
  std::array<Program, kVariants> programs;
  std::array<std::array<Program, kVariants>, 2> receiverPrograms;  // [ProbeLookup][variant]
  Program flatProgram, depthProgram;
  std::array<Program, kVariants> cutoutDepthPrograms{};  // by material variant, linked on first use
  const Program& cutoutDepthProgram(int variant);
  bool bakedDirect = false;  // every baked instance holds the direct part of its transfer
  // Shadow maps: a depth texture array (lights × cascades layers) and the framebuffer drawing it.
  GLuint shadowTexture = 0, shadowFbo = 0;
  int shadowSize = 0, shadowLayers = 0;
  bool warnedBakedDirect = false, warnedProbeDirect = false;
  // Probe grid: lattice index, static per-probe data, per-frame radiance (buffer + texture each).
  const ProbeGrid* grid = nullptr;
  GLuint probeBuffers[3] = {}, probeTextures[3] = {};
  // Background (Frame::background): its program, an empty vertex array for the full-screen
  // triangle, and the environment maps uploaded so far, by image (kept alive while uploaded).
  struct BackgroundProgram {
    GLuint id = 0;
    GLint camera = -1, tan = -1, ortho = -1, viewport = -1, mapCount = -1, worldToMap = -1, mapScale = -1,
          capCount = -1, caps = -1, capRadiance = -1, uniformRadiance = -1;
  } background;
  GLuint emptyVao = 0;
  std::map<const ImageRgb*, std::pair<std::shared_ptr<const ImageRgb>, GLuint>> envTextures;
  // The framebuffer drawn into (multisampled when Frame::samples > 1) and, when it is, the
  // single-sample one it is resolved into for the read-back.
  GLuint fbo = 0, colorRb = 0, depthRb = 0, resolveFbo = 0, resolveRb = 0;
  int fboWidth = 0, fboHeight = 0, fboSamples = 0, fboActualSamples = 1;
  std::vector<glm::vec4> readback;
  std::vector<glm::vec4> radiance;  // per-frame upload: c_p as RGBA (see uploadProbes)
  FrameStats stats;
  std::vector<std::string> warnings;

  Impl(GlContext& c) : context(c), gl(c.gl()) {}
  void checkError(const char* where) const;
  GLuint compile(GLenum type, const char* source, const char* what) const;
  Program link(const std::string& vs, const std::string& fs, const char* what) const;
  // A 2D float texture, bilinear, one level, the given wrap modes.
  GLuint linearFloatTexture(GLenum internalFormat, GLenum format, int width, int height, const void* texels,
                            GLint wrapS, GLint wrapT) const;
  GLuint uploadTexture(const Texture& t);
  void setMaterial(const Scene& scene, const MeshInstance& m, Instance& in);
  void upload(const Scene& scene);
  void uploadProbes(const ProbeGrid& grid);
  // The program of a material variant, linked on first use (DIRECT variants are only needed
  // once a frame has direct lights).
  const Program& bakedProgram(int variant);
  const Program& receiverProgram(ProbeLookup lookup, int variant);
  void ensureShadowMaps(int size, int layers);
  // The shadow maps of the frame's direct lights (when Frame::shadows.enabled) and the direct
  // uniforms of the DIRECT programs the frame uses.
  void drawShadows(const Frame& frame, double aspect, int height, bool drawReceivers, int bakedExtra,
                   int receiverExtra);
  void releaseShadowMaps();
  void releaseProbes();
  void ensureFramebuffer(int width, int height, int samples);
  void releaseFramebuffer();
  GLuint environmentTexture(const std::shared_ptr<const ImageRgb>& image);
  void drawBackground(const RigBackground& b, const CameraView& camera, int width, int height);
  void release();
  void uploadBounce(const std::vector<std::vector<glm::vec3>>* front, const std::vector<std::vector<glm::vec3>>* back);
};

void Renderer::Impl::checkError(const char* where) const {
  const GLenum e = gl.GetError();
  if (e != GL_NO_ERROR) throw Error(cat("GL: ", glErrorName(e), " ", where));
}

GLuint Renderer::Impl::compile(GLenum type, const char* source, const char* what) const {
  GLuint s = gl.CreateShader(type);
  gl.ShaderSource(s, 1, &source, nullptr);
  gl.CompileShader(s);
  GLint ok = 0;
  gl.GetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    gl.GetShaderInfoLog(s, sizeof log, nullptr, log);
    gl.DeleteShader(s);
    throw Error(cat("GL: ", what, " shader does not compile: ", log));
  }
  return s;
}

Renderer::Impl::Program Renderer::Impl::link(const std::string& vsSource, const std::string& fsSource,
                                             const char* what) const {
  GLuint vs = compile(GL_VERTEX_SHADER, vsSource.c_str(), cat(what, " vertex").c_str());
  GLuint fs = 0;
  try {
    fs = compile(GL_FRAGMENT_SHADER, fsSource.c_str(), cat(what, " fragment").c_str());
  } catch (...) {
    gl.DeleteShader(vs);
    throw;
  }
  Program p;
  p.id = gl.CreateProgram();
  gl.AttachShader(p.id, vs);
  gl.AttachShader(p.id, fs);
  gl.LinkProgram(p.id);
  gl.DeleteShader(vs);
  gl.DeleteShader(fs);
  GLint ok = 0;
  gl.GetProgramiv(p.id, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    gl.GetProgramInfoLog(p.id, sizeof log, nullptr, log);
    gl.DeleteProgram(p.id);
    throw Error(cat("GL: ", what, " shader program does not link: ", log));
  }
  auto loc = [&](const char* name) { return gl.GetUniformLocation(p.id, name); };
  p.viewProj = loc("uViewProj");
  p.model = loc("uModel");
  p.normalMatrix = loc("uNormalMatrix");
  p.light = bands <= kMaxAttributeBands ? loc("uLightFlat") : loc("uLight");
  if (p.light < 0) p.light = loc("uLight");
  if (p.light < 0) p.light = loc("uLightPacked");
  p.baseColor = loc("uBaseColor");
  p.origin = loc("uOrigin");
  p.spacing = loc("uSpacing");
  p.dims = loc("uDims");
  p.nearZero = loc("uNearZero");
  p.alphaCutoff = loc("uAlphaCutoff");
  p.opacity = loc("uOpacity");
  p.directSh = loc("uDirectSh");
  p.directCount = loc("uDirectCount");
  p.directDir = loc("uDirectDir");
  p.directIrradiance = loc("uDirectIrradiance");
  p.shadowed = loc("uShadowed");
  p.cascades = loc("uCascades");
  p.cascadeFar = loc("uCascadeFar");
  p.viewOrigin = loc("uViewOrigin");
  p.viewForward = loc("uViewForward");
  p.shadowSize = loc("uShadowSize");
  p.shadowMatrix = loc("uShadowMatrix");
  p.shadowParams = loc("uShadowParams");
  p.loopStep = loc("uLoopStep");
  return p;
}

GLuint Renderer::Impl::linearFloatTexture(GLenum internalFormat, GLenum format, int width, int height,
                                          const void* texels, GLint wrapS, GLint wrapT) const {
  GLuint tex = 0;
  gl.CreateTextures(GL_TEXTURE_2D, 1, &tex);
  gl.TextureStorage2D(tex, 1, internalFormat, width, height);
  gl.PixelStorei(GL_UNPACK_ALIGNMENT, 4);
  gl.TextureSubImage2D(tex, 0, 0, 0, width, height, format, GL_FLOAT, texels);
  gl.TextureParameteri(tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  gl.TextureParameteri(tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  gl.TextureParameteri(tex, GL_TEXTURE_WRAP_S, wrapS);
  gl.TextureParameteri(tex, GL_TEXTURE_WRAP_T, wrapT);
  return tex;
}

GLuint Renderer::Impl::uploadTexture(const Texture& t) {
  // Texels are already linear (sRGB-decoded by the loader), so a float texture keeps them
  // exact; row 0 (v = 0) goes to t = 0, which is where glTF's v = 0 samples it.
  const GLuint tex = linearFloatTexture(GL_RGBA32F, GL_RGBA, t.width, t.height, t.texels.data(), wrapMode(t.wrapS),
                                        wrapMode(t.wrapT));
  checkError(cat("uploading texture '", t.name, "'").c_str());
  return tex;
}

void Renderer::Impl::setMaterial(const Scene& scene, const MeshInstance& m, Instance& in) {
  in.indexCount = GLsizei(m.indices.size());
  in.triangles = m.triangleCount();
  in.hasColor = !m.colors.empty();
  in.variant = in.hasColor ? kVariantColor : 0;
  if (m.material < 0) return;
  const Material& mat = scene.materials.at(size_t(m.material));
  in.baseColor = mat.baseColorFactor;
  in.doubleSided = mat.doubleSided;
  // Transmission: thin and untinted, as in the bake: the background shows through 1 − opacity,
  // opacity = 1 − factor × the transmission texture's R (sampled in the shader).
  in.opacity = 1.0f - std::clamp(mat.transmissionFactor, 0.0f, 1.0f);
  in.alphaCutoff = mat.alphaCutoff;
  if (mat.alphaMode == Material::AlphaMode::Mask) in.variant |= kVariantMask;
  if (mat.alphaMode == Material::AlphaMode::Blend) in.variant |= kVariantBlend;
  in.blend = mat.alphaMode == Material::AlphaMode::Blend || mat.transmissionFactor > 0.0f;
  if (mat.baseColorTexture >= 0 && !m.texcoords.empty()) {
    GLuint& tex = textures.at(size_t(mat.baseColorTexture));
    if (!tex) tex = uploadTexture(scene.textures[size_t(mat.baseColorTexture)]);
    in.texture = tex;
    in.variant |= kVariantTexture;
  }
  if (mat.transmissionFactor > 0.0f && mat.transmissionTexture >= 0 && !m.texcoords.empty()) {
    GLuint& tex = textures.at(size_t(mat.transmissionTexture));
    if (!tex) tex = uploadTexture(scene.textures[size_t(mat.transmissionTexture)]);
    in.transmissionTexture = tex;
    in.variant |= kVariantTransmission;
  }
}

void Renderer::Impl::upload(const Scene& scene) {
  boundsMin = scene.boundsMin;
  boundsMax = scene.boundsMax;
  animation = scene;  // the SceneAnimation part only
  const size_t n2 = size_t(bands) * bands;
  GLint maxSsbo = 0;
  gl.GetIntegerv(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &maxSsbo);
  textures.assign(scene.textures.size(), 0);

  auto store = [&](GLuint buffer, const auto& v) {
    // Empty buffers are still created, with one byte: a zero-size store is an error.
    const size_t bytes = v.size() * sizeof(v[0]);
    gl.NamedBufferStorage(buffer, GLsizeiptr(std::max<size_t>(bytes, 1)), bytes ? v.data() : nullptr, 0);
  };
  auto attribute = [&](GLuint vao, GLuint location, GLuint buffer, GLint components, bool present) {
    if (!present) return;  // the shader ignores it (uHasColor) or the texture is not sampled
    gl.VertexArrayVertexBuffer(vao, location, buffer, 0, GLsizei(components * sizeof(float)));
    gl.VertexArrayAttribFormat(vao, location, components, GL_FLOAT, GL_FALSE, 0);
    gl.VertexArrayAttribBinding(vao, location, location);
    gl.EnableVertexArrayAttrib(vao, location);
  };

  for (const MeshInstance& m : scene.meshes) {
    if (m.receiverOnly) {
      // Drawn from the probe grid: positions, normals, texcoords, colours; no transfer.
      Instance in;
      setMaterial(scene, m, in);
      in.placement.name = m.name;
      in.placement.node = m.node;
      in.placement.world = m.world;
      in.restLo = glm::dvec3(1e300);
      in.restHi = glm::dvec3(-1e300);
      for (const glm::vec3& p : m.positions) {
        in.restLo = glm::min(in.restLo, glm::dvec3(p));
        in.restHi = glm::max(in.restHi, glm::dvec3(p));
      }
      gl.CreateBuffers(6, in.buffers);
      store(in.buffers[0], m.positions);
      store(in.buffers[1], m.texcoords);
      store(in.buffers[2], m.colors);
      store(in.buffers[3], m.indices);
      store(in.buffers[4], std::vector<float>());
      store(in.buffers[5], m.normals);
      gl.CreateVertexArrays(1, &in.vao);
      attribute(in.vao, 0, in.buffers[0], 3, true);
      attribute(in.vao, 1, in.buffers[1], 2, !m.texcoords.empty());
      attribute(in.vao, 2, in.buffers[2], 4, in.hasColor);
      attribute(in.vao, 3, in.buffers[5], 3, m.normals.size() == m.positions.size());
      gl.VertexArrayElementBuffer(in.vao, in.buffers[3]);
      checkError(cat("uploading receiver '", m.name, "'").c_str());
      receivers.push_back(in);
      continue;
    }
    if (m.transfer.empty()) {
      warnings.push_back(cat("skipping unbaked instance '", m.name, "': no transfer and not a receiver"));
      continue;
    }
    if (m.transfer.size() != m.vertexCount() * n2)
      throw Error(cat(scene.path, ": instance '", m.name, "': transfer holds ", m.transfer.size(),
                      " values, expected ", m.vertexCount() * n2, " (", m.vertexCount(), " vertices, ", bands,
                      " bands)"));
    // The back side is drawn where the material is double-sided (a one-sided back is culled).
    const bool twoSided = m.hasBackTransfer() && m.material >= 0 && scene.materials.at(size_t(m.material)).doubleSided;
    if (twoSided && m.transferBack.size() != m.transfer.size())
      throw Error(cat(scene.path, ": instance '", m.name, "': back-side transfer holds ", m.transferBack.size(),
                      " values, expected ", m.transfer.size()));
    const size_t transferBytes = m.transfer.size() * sizeof(glm::vec3);
    if ((bands > kMaxAttributeBands || twoSided) && transferBytes > size_t(maxSsbo))
      throw Error(cat(scene.path, ": instance '", m.name, "': transfer of ", transferBytes >> 20,
                      " MiB exceeds the GL's shader storage block limit of ", maxSsbo >> 20, " MiB"));

    // The direct part (t⁰) on every side drawn, else the direct lights go through SH.
    const bool direct = m.transferDirect.size() == m.vertexCount() * n2 &&
                        (!twoSided || m.transferDirectBack.size() == m.vertexCount() * n2) &&
                        m.normals.size() == m.vertexCount();
    if (m.hasDirectTransfer() && !direct)
      throw Error(cat(scene.path, ": instance '", m.name, "': direct transfer holds ", m.transferDirect.size(),
                      " values (back ", m.transferDirectBack.size(), "), expected ", m.vertexCount() * n2));
    bakedDirect = (instances.empty() || bakedDirect) && direct;

    Instance in;
    setMaterial(scene, m, in);
    if (twoSided) in.variant |= kVariantTwoSided;
    bakedProgram(in.variant);
    gl.CreateBuffers(6, in.buffers);
    store(in.buffers[0], m.positions);
    store(in.buffers[1], m.texcoords);
    store(in.buffers[2], m.colors);
    store(in.buffers[3], m.indices);
    store(in.buffers[4], m.transfer);
    store(in.buffers[5], direct ? m.normals : std::vector<glm::vec3>());
    if (twoSided) {
      gl.CreateBuffers(1, &in.backTransfer);
      store(in.backTransfer, m.transferBack);
    }
    in.mesh = size_t(&m - scene.meshes.data());
    in.vertices = m.vertexCount();
    in.restLo = glm::dvec3(1e300);
    in.restHi = glm::dvec3(-1e300);
    for (const glm::vec3& q : m.positions) {
      in.restLo = glm::min(in.restLo, glm::dvec3(q));
      in.restHi = glm::max(in.restHi, glm::dvec3(q));
    }
    if (direct) {
      gl.CreateBuffers(twoSided ? 2 : 1, in.directTransfer);
      store(in.directTransfer[0], m.transferDirect);
      if (twoSided) store(in.directTransfer[1], m.transferDirectBack);
      gl.CreateBuffers(twoSided ? 2 : 1, in.directBounce);
      const std::vector<glm::vec3> zeros(m.vertexCount(), glm::vec3(0.0f));
      for (int side = 0; side < (twoSided ? 2 : 1); ++side)
        gl.NamedBufferStorage(in.directBounce[side], GLsizeiptr(std::max<size_t>(zeros.size() * sizeof(glm::vec3), 1)),
                              zeros.empty() ? nullptr : zeros.data(), GL_DYNAMIC_STORAGE_BIT);
    }

    gl.CreateVertexArrays(1, &in.vao);
    attribute(in.vao, 0, in.buffers[0], 3, true);
    attribute(in.vao, 1, in.buffers[1], 2, !m.texcoords.empty());
    attribute(in.vao, 2, in.buffers[2], 4, in.hasColor);
    attribute(in.vao, kNormalAttribute, in.buffers[5], 3, direct);
    if (bands <= kMaxAttributeBands) {
      const GLsizei stride = GLsizei(n2 * sizeof(glm::vec3));
      gl.VertexArrayVertexBuffer(in.vao, kFirstTransferAttribute, in.buffers[4], 0, stride);
      const int floats = int(3 * n2);
      for (int k = 0; k < attributeChunks(bands); ++k) {
        // A last chunk of fewer than 4 floats reads w = 1, multiplied by the light's zero pad.
        const GLuint location = kFirstTransferAttribute + GLuint(k);
        gl.VertexArrayAttribFormat(in.vao, location, std::min(4, floats - 4 * k), GL_FLOAT,
                                   GL_FALSE, GLuint(16 * k));
        gl.VertexArrayAttribBinding(in.vao, location, kFirstTransferAttribute);
        gl.EnableVertexArrayAttrib(in.vao, location);
      }
    }
    gl.VertexArrayElementBuffer(in.vao, in.buffers[3]);
    checkError(cat("uploading instance '", m.name, "'").c_str());
    instances.push_back(in);
  }
  if (instances.empty() && receivers.empty())
    throw Error(cat(scene.path, ": no baked instance or receiver to render"));
}

const Renderer::Impl::Program& Renderer::Impl::cutoutDepthProgram(int variant) {
  variant &= kVariantTexture | kVariantColor | kVariantMask | kVariantBlend | kVariantTransmission;
  Program& p = cutoutDepthPrograms[size_t(variant)];
  if (!p.id)
    p = link(withMaterialDefines(cutoutDepthVertexShader(), variant),
             withMaterialDefines(cutoutDepthFragmentShader(), variant), "shadow map (cutouts)");
  return p;
}

const Renderer::Impl::Program& Renderer::Impl::bakedProgram(int variant) {
  Program& p = programs[size_t(variant)];
  if (!p.id)
    p = link(withMaterialDefines(bakedVertexShader(bands), variant), withMaterialDefines(bakedFragmentShader(), variant),
             "baked");
  return p;
}

const Renderer::Impl::Program& Renderer::Impl::receiverProgram(ProbeLookup lookup, int variant) {
  Program& p = receiverPrograms[size_t(lookup)][size_t(variant)];
  if (!p.id) {
    p = link(withMaterialDefines(receiverVertexShader(grid->bands, lookup), variant),
             withMaterialDefines(receiverFragmentShader(grid->bands, lookup), variant), "receiver");
    const glm::vec3 origin(grid->origin), spacing(grid->spacing);
    gl.ProgramUniform3fv(p.id, p.origin, 1, &origin.x);
    gl.ProgramUniform3fv(p.id, p.spacing, 1, &spacing.x);
    gl.ProgramUniform3iv(p.id, p.dims, 1, &grid->dims.x);
    gl.ProgramUniform1f(p.id, p.nearZero, float(nearZero(*grid)));
  }
  return p;
}

void Renderer::Impl::releaseShadowMaps() {
  if (shadowTexture) gl.DeleteTextures(1, &shadowTexture);
  if (shadowFbo) gl.DeleteFramebuffers(1, &shadowFbo);
  shadowTexture = shadowFbo = 0;
  shadowSize = shadowLayers = 0;
}

void Renderer::Impl::ensureShadowMaps(int size, int layers) {
  if (shadowTexture && size == shadowSize && layers <= shadowLayers) return;
  GLint maxSize = 0, maxLayers = 0;
  gl.GetIntegerv(GL_MAX_TEXTURE_SIZE, &maxSize);
  gl.GetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &maxLayers);
  if (size > maxSize || layers > maxLayers)
    throw Error(cat("render: ", layers, " shadow maps of ", size, "x", size, " exceed the GL's limits (", maxSize,
                    " texels a side, ", maxLayers, " layers)"));
  releaseShadowMaps();
  gl.CreateTextures(GL_TEXTURE_2D_ARRAY, 1, &shadowTexture);
  gl.TextureStorage3D(shadowTexture, 1, GL_DEPTH_COMPONENT32F, size, size, layers);
  gl.TextureParameteri(shadowTexture, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  gl.TextureParameteri(shadowTexture, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  gl.TextureParameteri(shadowTexture, GL_TEXTURE_COMPARE_MODE, GL_NONE);
  gl.TextureParameteri(shadowTexture, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  gl.TextureParameteri(shadowTexture, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  gl.CreateFramebuffers(1, &shadowFbo);
  gl.NamedFramebufferTextureLayer(shadowFbo, GL_DEPTH_ATTACHMENT, shadowTexture, 0, 0);
  gl.NamedFramebufferDrawBuffer(shadowFbo, GL_NONE);
  gl.NamedFramebufferReadBuffer(shadowFbo, GL_NONE);
  const GLenum status = gl.CheckNamedFramebufferStatus(shadowFbo, GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    throw Error(cat("GL: shadow-map framebuffer incomplete (", glErrorName(status), ")"));
  checkError("creating the shadow maps");
  shadowSize = size;
  shadowLayers = layers;
}

void Renderer::Impl::releaseProbes() {
  if (probeTextures[0]) gl.DeleteTextures(3, probeTextures);
  if (probeBuffers[0]) gl.DeleteBuffers(3, probeBuffers);
  for (GLuint& t : probeTextures) t = 0;
  for (GLuint& b : probeBuffers) b = 0;
  for (auto& lookup : receiverPrograms)
    for (Program& p : lookup) {
      if (p.id) gl.DeleteProgram(p.id);
      p = Program{};
    }
  grid = nullptr;
}

void Renderer::Impl::uploadProbes(const ProbeGrid& g) {
  if (g.bands < 1 || g.bands > sh::kMaxBands) throw Error(cat("probe grid: ", g.bands, " bands, expected 1..", sh::kMaxBands));
  if (g.dims.x < 1 || g.dims.y < 1 || g.dims.z < 1)
    throw Error(cat("probe grid: dims ", g.dims.x, "x", g.dims.y, "x", g.dims.z, ", expected at least 1 per axis"));
  if (g.transfer.size() != g.probeCount() * g.transferStride() || g.validity.size() != g.probeCount() ||
      g.offset.size() != g.probeCount() || g.moments.size() != g.probeCount())
    throw Error("probe grid: per-probe arrays do not match the probe count");
  releaseProbes();
  // Buffer textures (texelFetch by index): the weights are per corner, so the hardware's
  // trilinear filtering of a 3D texture is of no use, and a buffer holds any lattice and band
  // count without 3D size limits.
  GLint maxTexels = 0;
  gl.GetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &maxTexels);
  const std::vector<int32_t> lattice = latticeIndex(g);
  const std::vector<glm::vec4> statics = probeStaticTexels(g);
  const size_t radianceCount = (g.probeCount() + 1) * size_t(radianceTexels(g.bands));
  for (size_t texels : {lattice.size(), statics.size(), radianceCount})
    if (texels > size_t(maxTexels))
      throw Error(cat("probe grid: ", texels, " texels exceed the GL's texture buffer limit of ", maxTexels));
  grid = &g;
  for (ProbeLookup lookup : {ProbeLookup::PerPixel, ProbeLookup::PerVertex})
    for (const Instance& in : receivers) receiverProgram(lookup, in.variant);
  gl.CreateBuffers(3, probeBuffers);
  gl.NamedBufferStorage(probeBuffers[0], GLsizeiptr(lattice.size() * sizeof(int32_t)), lattice.data(), 0);
  gl.NamedBufferStorage(probeBuffers[1], GLsizeiptr(statics.size() * sizeof(glm::vec4)), statics.data(), 0);
  gl.NamedBufferStorage(probeBuffers[2], GLsizeiptr(radianceCount * sizeof(glm::vec4)), nullptr,
                        GL_DYNAMIC_STORAGE_BIT);
  gl.CreateTextures(GL_TEXTURE_BUFFER, 3, probeTextures);
  gl.TextureBuffer(probeTextures[0], GL_R32I, probeBuffers[0]);
  gl.TextureBuffer(probeTextures[1], GL_RGBA32F, probeBuffers[1]);
  gl.TextureBuffer(probeTextures[2], GL_RGBA32F, probeBuffers[2]);
  checkError("uploading the probe grid");
}

void Renderer::Impl::releaseFramebuffer() {
  if (fbo) gl.DeleteFramebuffers(1, &fbo);
  if (resolveFbo) gl.DeleteFramebuffers(1, &resolveFbo);
  for (GLuint* rb : {&colorRb, &depthRb, &resolveRb})
    if (*rb) gl.DeleteRenderbuffers(1, rb);
  fbo = resolveFbo = colorRb = depthRb = resolveRb = 0;
}

void Renderer::Impl::ensureFramebuffer(int width, int height, int samples) {
  if (fbo && width == fboWidth && height == fboHeight && samples == fboSamples) return;
  GLint maxSize = 0, maxSamples = 0;
  gl.GetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &maxSize);
  gl.GetIntegerv(GL_MAX_SAMPLES, &maxSamples);
  if (width <= 0 || height <= 0 || width > maxSize || height > maxSize)
    throw Error(cat("render: frame size ", width, "x", height, " outside 1..", maxSize));
  if (samples < 1 || samples > std::max(maxSamples, 1) || (samples & (samples - 1)) != 0)
    throw Error(cat("render: ", samples, " samples per pixel; this GL allows 1, 2, 4 ... up to ", std::max(maxSamples, 1)));
  releaseFramebuffer();
  auto makeFbo = [&](GLuint& f, GLuint& color, GLuint* depth, int n) {
    gl.CreateRenderbuffers(1, &color);
    if (n > 1)
      gl.NamedRenderbufferStorageMultisample(color, n, GL_RGBA32F, width, height);
    else
      gl.NamedRenderbufferStorage(color, GL_RGBA32F, width, height);
    gl.CreateFramebuffers(1, &f);
    gl.NamedFramebufferRenderbuffer(f, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color);
    if (depth) {
      gl.CreateRenderbuffers(1, depth);
      if (n > 1)
        gl.NamedRenderbufferStorageMultisample(*depth, n, GL_DEPTH_COMPONENT32F, width, height);
      else
        gl.NamedRenderbufferStorage(*depth, GL_DEPTH_COMPONENT32F, width, height);
      gl.NamedFramebufferRenderbuffer(f, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, *depth);
    }
    gl.NamedFramebufferDrawBuffer(f, GL_COLOR_ATTACHMENT0);
    gl.NamedFramebufferReadBuffer(f, GL_COLOR_ATTACHMENT0);
    const GLenum status = gl.CheckNamedFramebufferStatus(f, GL_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE)
      throw Error(cat("GL: RGBA32F framebuffer of ", n, " samples incomplete (", glErrorName(status), ")"));
  };
  makeFbo(fbo, colorRb, &depthRb, samples);
  if (samples > 1) makeFbo(resolveFbo, resolveRb, nullptr, 1);
  // The GL may give more samples than asked for (llvmpipe: 4 for 2).
  GLint actual = 0;
  gl.GetNamedRenderbufferParameteriv(colorRb, GL_RENDERBUFFER_SAMPLES, &actual);
  fboActualSamples = std::max(actual, 1);
  checkError("creating the framebuffer");
  fboWidth = width;
  fboHeight = height;
  fboSamples = samples;
}

GLuint Renderer::Impl::environmentTexture(const std::shared_ptr<const ImageRgb>& image) {
  auto it = envTextures.find(image.get());
  if (it != envTextures.end()) return it->second.second;
  GLint maxSize = 0;
  gl.GetIntegerv(GL_MAX_TEXTURE_SIZE, &maxSize);
  if (image->width < 1 || image->height < 1 || image->width > maxSize || image->height > maxSize)
    throw Error(cat("background: environment map of ", image->width, "x", image->height,
                    " pixels exceeds the GL's texture size limit of ", maxSize));
  // Row 0 (v near 0, towards +Y) at t = 0, repeating in u, clamped in v: texture(u, v) is
  // sampleEquirect's bilinear lookup.
  const GLuint tex = linearFloatTexture(GL_RGB32F, GL_RGB, image->width, image->height, image->pixels.data(),
                                        GL_REPEAT, GL_CLAMP_TO_EDGE);
  checkError("uploading an environment map for the background");
  envTextures.emplace(image.get(), std::make_pair(image, tex));
  return tex;
}

void checkBackgroundSize(const std::string& what, size_t maps, size_t caps) {
  if (maps > size_t(kMaxBackgroundMaps))
    throw Error(cat(what, ": ", maps, " environment maps, at most ", kMaxBackgroundMaps, " can be drawn"));
  if (caps > size_t(kMaxBackgroundCaps))
    throw Error(cat(what, ": ", caps, " suns and disks, at most ", kMaxBackgroundCaps, " can be drawn"));
}

void Renderer::Impl::drawBackground(const RigBackground& b, const CameraView& camera, int width, int height) {
  checkBackgroundSize("background", b.maps.size(), b.caps.size());
  if (!background.id) {
    const Program p = link(backgroundVertexShader(), backgroundFragmentShader(), "background");
    background.id = p.id;
    auto loc = [&](const char* name) { return gl.GetUniformLocation(background.id, name); };
    background.camera = loc("uCamera");
    background.tan = loc("uTan");
    background.ortho = loc("uOrtho");
    background.viewport = loc("uViewport");
    background.mapCount = loc("uMapCount");
    background.worldToMap = loc("uWorldToMap");
    background.mapScale = loc("uMapScale");
    background.capCount = loc("uCapCount");
    background.caps = loc("uCaps");
    background.capRadiance = loc("uCapRadiance");
    background.uniformRadiance = loc("uUniformRadiance");
    gl.CreateVertexArrays(1, &emptyVao);
  }
  const GLuint id = background.id;
  const glm::mat3 rotation(glm::dmat3(camera.cameraToWorld));
  const double tanY = std::tan(0.5 * camera.yfov);
  const glm::vec2 tans(float(tanY * width / height), float(tanY));
  const glm::vec2 viewport{float(width), float(height)};
  gl.ProgramUniformMatrix3fv(id, background.camera, 1, GL_FALSE, &rotation[0][0]);
  gl.ProgramUniform2fv(id, background.tan, 1, &tans.x);
  gl.ProgramUniform1i(id, background.ortho, camera.perspective ? 0 : 1);
  gl.ProgramUniform2fv(id, background.viewport, 1, &viewport.x);
  gl.ProgramUniform1i(id, background.mapCount, GLint(b.maps.size()));
  for (size_t i = 0; i < b.maps.size(); ++i) {
    const glm::mat3 m(b.maps[i].worldToMap);
    const glm::vec3 scale(b.maps[i].scale);
    gl.ProgramUniformMatrix3fv(id, background.worldToMap + GLint(i), 1, GL_FALSE, &m[0][0]);
    gl.ProgramUniform3fv(id, background.mapScale + GLint(i), 1, &scale.x);
    gl.BindTextureUnit(GLuint(4 + i), environmentTexture(b.maps[i].image));
  }
  std::vector<glm::vec4> caps, capRadiance;
  for (const RigBackground::Cap& c : b.caps) {
    caps.emplace_back(glm::vec3(c.direction), float(c.cosRadius));
    capRadiance.emplace_back(glm::vec3(c.radiance), 0.0f);
  }
  gl.ProgramUniform1i(id, background.capCount, GLint(caps.size()));
  if (!caps.empty()) {
    gl.ProgramUniform4fv(id, background.caps, GLsizei(caps.size()), &caps[0].x);
    gl.ProgramUniform4fv(id, background.capRadiance, GLsizei(caps.size()), &capRadiance[0].x);
  }
  const glm::vec3 uniform(b.uniform);
  gl.ProgramUniform3fv(id, background.uniformRadiance, 1, &uniform.x);
  gl.UseProgram(id);
  gl.Disable(GL_CULL_FACE);
  gl.DepthFunc(GL_EQUAL);
  gl.BindVertexArray(emptyVao);
  gl.DrawArrays(GL_TRIANGLES, 0, 3);
  gl.DepthFunc(GL_GREATER);
  checkError("drawing the background");
}

// The shadow-map pass (docs/render.md, "Direct lights and their shadows"): every opaque baked
// instance and every drawn receiver (at the frame's time) into one depth layer per light and
// cascade, both faces (culling off: a double-sided sheet casts from either side), then the
// direct uniforms of the DIRECT programs. BLEND and transmissive instances cast no shadow here.
void Renderer::Impl::drawShadows(const Frame& frame, double aspect, int height, bool drawReceivers, int bakedExtra,
                                 int receiverExtra) {
  const auto t0 = std::chrono::steady_clock::now();
  const ShadowSettings& settings = frame.shadows;
  ShadowPlan plan;
  // No direct light (a frame lit only by a gathered sky detail): no maps, a light count of 0.
  const bool maps = settings.enabled && !frame.direct.empty();
  if (maps) {
    // The casters: the scene's bounds and, where they moved, the receivers'.
    glm::dvec3 lo(boundsMin), hi(boundsMax);
    std::vector<glm::dmat4> motions;
    for (const Instance& in : receivers) {
      motions.push_back(instanceMotion(animation, in.placement, frame.time));
      if (!drawReceivers || in.restLo.x > in.restHi.x) continue;
      for (int i = 0; i < 8; ++i) {
        const glm::dvec3 c(i & 1 ? in.restHi.x : in.restLo.x, i & 2 ? in.restHi.y : in.restLo.y,
                           i & 4 ? in.restHi.z : in.restLo.z);
        const glm::dvec3 w(motions.back() * glm::dvec4(c, 1.0));
        lo = glm::min(lo, w);
        hi = glm::max(hi, w);
      }
    }
    plan = planShadows(frame.direct, frame.camera, aspect, height, lo, hi, settings.mapSize, settings.maxCascades);
    const int layers = int(plan.layers.size());
    ensureShadowMaps(settings.mapSize, layers);
    gl.BindFramebuffer(GL_FRAMEBUFFER, shadowFbo);
    gl.Viewport(0, 0, settings.mapSize, settings.mapSize);
    gl.ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
    gl.Enable(GL_DEPTH_TEST);
    gl.DepthFunc(GL_LESS);
    gl.Disable(GL_CULL_FACE);
    const float one = 1.0f;
    for (int layer = 0; layer < layers; ++layer) {
      gl.NamedFramebufferTextureLayer(shadowFbo, GL_DEPTH_ATTACHMENT, shadowTexture, 0, layer);
      gl.ClearNamedFramebufferfv(shadowFbo, GL_DEPTH, 0, &one);
      const glm::dmat4 viewProj = plan.layers[size_t(layer)].viewProj();
      const glm::mat4 vp(viewProj), identity(1.0f);
      // Opaque casters with the plain depth program; those that let light through with their
      // material's (cutoutDepthProgram).
      GLuint current = 0;  // the program in use: switched only between opaque and cutout casters
      auto cast = [&](const Instance& in, const glm::mat4& model) {
        const bool cutout = in.blend || (in.variant & kVariantMask);
        const Program& p = cutout ? cutoutDepthProgram(in.variant) : depthProgram;
        if (p.id != current) {
          gl.UseProgram(p.id);
          gl.ProgramUniformMatrix4fv(p.id, p.viewProj, 1, GL_FALSE, &vp[0][0]);
          current = p.id;
        }
        gl.ProgramUniformMatrix4fv(p.id, p.model, 1, GL_FALSE, &model[0][0]);
        if (cutout) {
          gl.ProgramUniform4fv(p.id, p.baseColor, 1, &in.baseColor.x);
          gl.ProgramUniform1f(p.id, p.opacity, in.opacity);
          if (p.alphaCutoff >= 0) gl.ProgramUniform1f(p.id, p.alphaCutoff, in.alphaCutoff);
          if (in.texture) gl.BindTextureUnit(0, in.texture);
          if (in.transmissionTexture) gl.BindTextureUnit(kTransmissionUnit, in.transmissionTexture);
        }
        gl.BindVertexArray(in.vao);
        gl.DrawElements(GL_TRIANGLES, in.indexCount, GL_UNSIGNED_INT, nullptr);
      };
      for (const Instance& in : instances) cast(in, identity);
      if (drawReceivers)
        for (size_t k = 0; k < receivers.size(); ++k) cast(receivers[k], glm::mat4(motions[k]));
    }
    gl.BindVertexArray(0);
    gl.Finish();
    checkError("drawing the shadow maps");
    stats.shadowMaps = layers;
    stats.cascades = plan.cascades;
    stats.shadowMapSize = settings.mapSize;
  }

  // The direct uniforms, per DIRECT program in use.
  std::vector<glm::vec4> dirs, irradiance, params;
  std::vector<glm::mat4> matrices;
  for (const DirectLight& l : frame.direct) {
    const double radius = l.radius < kPointSunRadians ? 0.0 : l.radius;
    const double sin2 = std::sin(radius) * std::sin(radius);
    dirs.emplace_back(glm::vec3(glm::normalize(l.direction)), float(sin2));
    irradiance.emplace_back(glm::vec3(l.irradiance), radius > 0.0 ? float(1.0 / std::tan(radius)) : 0.0f);
  }
  for (const ShadowLayer& layer : plan.layers) {
    matrices.emplace_back(layer.worldToMap);
    params.emplace_back(float(layer.texel), float(layer.range), float(layer.tanRadius), 0.0f);
  }
  const glm::vec4 cascadeFar(plan.cascadeFar);
  const glm::vec3 origin(plan.viewOrigin), forward(plan.viewForward);
  auto set = [&](const Program& p) {
    gl.ProgramUniform1i(p.id, p.directCount, GLint(dirs.size()));
    gl.ProgramUniform1i(p.id, p.shadowed, maps ? 1 : 0);
    gl.ProgramUniform1i(p.id, p.loopStep, 1);
    if (dirs.empty()) return;
    gl.ProgramUniform4fv(p.id, p.directDir, GLsizei(dirs.size()), &dirs[0].x);
    gl.ProgramUniform4fv(p.id, p.directIrradiance, GLsizei(irradiance.size()), &irradiance[0].x);
    if (!maps) return;
    gl.ProgramUniform1i(p.id, p.cascades, plan.cascades);
    gl.ProgramUniform4fv(p.id, p.cascadeFar, 1, &cascadeFar.x);
    gl.ProgramUniform3fv(p.id, p.viewOrigin, 1, &origin.x);
    gl.ProgramUniform3fv(p.id, p.viewForward, 1, &forward.x);
    gl.ProgramUniform1i(p.id, p.shadowSize, settings.mapSize);
    gl.ProgramUniformMatrix4fv(p.id, p.shadowMatrix, GLsizei(matrices.size()), GL_FALSE, &matrices[0][0][0]);
    gl.ProgramUniform4fv(p.id, p.shadowParams, GLsizei(params.size()), &params[0].x);
  };
  if (bakedExtra)
    for (const Instance& in : instances) set(bakedProgram(in.variant | bakedExtra));
  if (receiverExtra)
    for (const Instance& in : receivers) set(receiverProgram(frame.probeLookup, in.variant | receiverExtra));
  checkError("setting the direct lights");
  stats.shadowMs = msSince(t0);
}

void Renderer::Impl::release() {
  for (std::vector<Instance>* list : {&instances, &receivers})
    for (Instance& in : *list) {
      gl.DeleteVertexArrays(1, &in.vao);
      gl.DeleteBuffers(6, in.buffers);
      if (in.backTransfer) gl.DeleteBuffers(1, &in.backTransfer);
      for (GLuint b : in.directTransfer)
        if (b) gl.DeleteBuffers(1, &b);
      for (GLuint b : in.directBounce)
        if (b) gl.DeleteBuffers(1, &b);
    }
  for (GLuint t : textures)
    if (t) gl.DeleteTextures(1, &t);
  releaseProbes();
  for (const Program& p : programs)
    if (p.id) gl.DeleteProgram(p.id);
  if (flatProgram.id) gl.DeleteProgram(flatProgram.id);
  if (depthProgram.id) gl.DeleteProgram(depthProgram.id);
  for (const Program& p : cutoutDepthPrograms)
    if (p.id) gl.DeleteProgram(p.id);
  releaseShadowMaps();
  if (background.id) gl.DeleteProgram(background.id);
  if (emptyVao) gl.DeleteVertexArrays(1, &emptyVao);
  for (auto& [image, entry] : envTextures) gl.DeleteTextures(1, &entry.second);
  envTextures.clear();
  releaseFramebuffer();
}

Renderer::Renderer(GlContext& context, const Scene& scene) : impl_(std::make_unique<Impl>(context)) {
  bool anyReceiver = false;
  for (const MeshInstance& m : scene.meshes) anyReceiver |= m.receiverOnly;
  if (scene.transferBands < 0 || scene.transferBands > sh::kMaxBands || (scene.transferBands == 0 && !anyReceiver))
    throw Error(cat(scene.path, ": holds no baked transfer (run prt bake first)"));
  impl_->bands = scene.transferBands;
  context.makeCurrent();
  try {
    impl_->flatProgram = impl_->link(flatVertexShader(), flatFragmentShader(), "flat");
    impl_->depthProgram = impl_->link(flatVertexShader(), depthFragmentShader(), "shadow map");
    impl_->upload(scene);
  } catch (...) {
    impl_->release();
    throw;
  }
}

Renderer::~Renderer() {
  // GL objects belong to the context: make it current so they are deleted there, not in
  // whichever context happens to be current. A failure here cannot be reported; leak instead.
  try {
    impl_->context.makeCurrent();
    impl_->release();
  } catch (const Error&) {
  }
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

// The direct lights' gathered bounce into each baked instance's bounce buffers (zeros where the
// frame gives none, written once until a bounce comes again).
void Renderer::Impl::uploadBounce(const std::vector<std::vector<glm::vec3>>* front,
                                  const std::vector<std::vector<glm::vec3>>* back) {
  for (Instance& in : instances) {
    if (!in.directBounce[0]) continue;
    if (!front && in.bounceZero) continue;
    const std::vector<glm::vec3> zeros(front ? 0 : in.vertices, glm::vec3(0.0f));
    for (int side = 0; side < 2; ++side) {
      if (!in.directBounce[side]) continue;
      const std::vector<std::vector<glm::vec3>>* given = side ? back : front;
      const std::vector<glm::vec3>* v = &zeros;
      if (given) {
        if (given->size() <= in.mesh || (*given)[in.mesh].size() != in.vertices)
          throw Error(cat("render: the direct lights' bounce holds ", given->size() > in.mesh ? (*given)[in.mesh].size() : 0,
                          " values for instance ", in.mesh, (side ? " (back side)" : ""), ", expected ", in.vertices));
        v = &(*given)[in.mesh];
      }
      if (!v->empty())
        gl.NamedBufferSubData(in.directBounce[side], 0, GLsizeiptr(v->size() * sizeof(glm::vec3)), v->data());
    }
    in.bounceZero = front == nullptr;
  }
}

ImageRgb Renderer::render(const Frame& frame) {
  Impl& r = *impl_;
  const GlFunctions& gl = r.gl;
  const CameraView& camera = frame.camera;
  const int width = frame.width > 0 ? frame.width : r.context.width();
  const int height = frame.height > 0 ? frame.height : r.context.height();
  const bool flat = frame.shading == Shading::Flat;
  const bool drawReceivers = r.grid != nullptr && !r.receivers.empty();
  if (frame.direct.size() > size_t(kMaxDirectLights))
    throw Error(cat("render: ", frame.direct.size(), " direct lights, at most ", kMaxDirectLights, " per frame"));
  const ShadowSettings& shadowSettings = frame.shadows;
  if (shadowSettings.mapSize < 16 || shadowSettings.mapSize > 8192 || shadowSettings.maxCascades < 1 ||
      shadowSettings.maxCascades > kMaxCascades)
    throw Error(cat("render: shadow maps of ", shadowSettings.mapSize, " texels and ", shadowSettings.maxCascades,
                    " cascades; expected 16..8192 and 1..", kMaxCascades));
  r.context.makeCurrent();

  // Direct lights: lit per pixel where the transfer holds its direct part (bakedSplit,
  // receiverSplit), else through SH with the rest of the light (warned once).
  const bool anyDirect = !flat && !frame.direct.empty();
  // A gathered irradiance (Frame::directBounce: the sky's detail) needs the split shader even
  // without direct lights.
  const bool bakedSplit = (anyDirect || (!flat && frame.directBounce)) && r.bakedDirect && !r.instances.empty();
  const bool receiverSplit = anyDirect && drawReceivers && r.grid->hasDirect();
  if (anyDirect && !r.instances.empty() && !r.bakedDirect && !r.warnedBakedDirect) {
    r.warnedBakedDirect = true;
    r.warnings.push_back(cat("the baked scene has no direct part of its transfer (baked by an older prt): its ",
                             frame.direct.size(), " direct light(s) are lit through SH, without exact shadows; bake "
                             "again for them"));
  }
  if (anyDirect && drawReceivers && !r.grid->hasDirect() && !r.warnedProbeDirect) {
    r.warnedProbeDirect = true;
    r.warnings.push_back(cat("the probe grid has no direct part (baked by an older prt): receivers get the ",
                             frame.direct.size(), " direct light(s) through SH, without exact shadows; bake the "
                             "probes again for them"));
  }
  r.stats.directBaked = bakedSplit ? frame.direct.size() : 0;
  r.stats.directReceivers = receiverSplit ? frame.direct.size() : 0;
  const int bakedExtra = bakedSplit ? kVariantDirect : 0, receiverExtra = receiverSplit ? kVariantDirect : 0;
  auto directSh = [&](int bands) {
    return frame.directLight.size() > 0 ? sh::resize(frame.directLight, bands) : sh::ShRgb(bands);
  };

  // Light update: the baked instances' light uniform, and the probes' incident radiance
  // c_p = M_p · l (CPU, TBB over probes) copied into the buffer the receivers read.
  const auto t0 = std::chrono::steady_clock::now();
  if (!flat && r.bands > 0) {
    // The whole light through t; with the split, t⁰ · directSh is taken off in the shader, or,
    // with a gathered bounce (Frame::directBounce), directSh stays out and the bounce is added.
    sh::ShRgb l = sh::resize(frame.light, r.bands);
    const bool gathered = bakedSplit && frame.directBounce != nullptr;
    const sh::ShRgb dl = gathered ? sh::ShRgb(r.bands) : directSh(r.bands);
    l += dl;
    if (bakedSplit) r.uploadBounce(gathered ? frame.directBounce : nullptr, gathered ? frame.directBounceBack : nullptr);
    if (bakedSplit)
      for (const Impl::Instance& in : r.instances) {
        const Impl::Program& p = r.bakedProgram(in.variant | kVariantDirect);
        gl.ProgramUniform3fv(p.id, p.directSh, dl.size(), &dl.c[0].x);
      }
    std::vector<glm::vec4> packed(size_t(attributeChunks(r.bands)), glm::vec4(0.0f));
    for (int i = 0; i < l.size(); ++i)
      for (int c = 0; c < 3; ++c) packed[size_t(3 * i + c) / 4][(3 * i + c) % 4] = l.c[size_t(i)][c];
    for (const Impl::Program& p : r.programs) {
      if (!p.id) continue;
      if (r.bands <= kMaxAttributeBands)
        gl.ProgramUniform4fv(p.id, p.light, GLsizei(packed.size()), &packed[0].x);
      else
        gl.ProgramUniform3fv(p.id, p.light, l.size(), &l.c[0].x);
    }
  }
  if (!flat && drawReceivers) {
    const ProbeGrid& g = *r.grid;
    sh::ShRgb l = sh::resize(frame.light, g.bands);
    const sh::ShRgb dl = directSh(g.bands);
    // Outside the grid (M = I, M⁰ = I) the split leaves the light without the direct lights' SH.
    if (!receiverSplit) l += dl;
    const std::vector<glm::vec4> packedLight = packLight(g.bands, l);
    for (const Impl::Instance& in : r.receivers) {
      const Impl::Program& p = r.receiverProgram(frame.probeLookup, in.variant | receiverExtra);
      gl.ProgramUniform4fv(p.id, p.light, GLsizei(packedLight.size()), &packedLight[0].x);
    }
    if (g.probeCount() > 0) {
      const std::vector<glm::vec3> relit = receiverSplit ? relightProbes(g, l, dl) : relightProbes(g, l);
      packRadiance(g.bands, relit, r.radiance);
      gl.NamedBufferSubData(r.probeBuffers[2], 0, GLsizeiptr(r.radiance.size() * sizeof(glm::vec4)), r.radiance.data());
    }
  }
  r.checkError("updating the light");
  r.stats.lightMs = msSince(t0);

  const auto t1 = std::chrono::steady_clock::now();
  r.ensureFramebuffer(width, height, frame.samples);
  r.stats.samples = r.fboActualSamples;
  const double aspect = double(width) / height;
  r.stats.shadowMs = 0.0;
  r.stats.shadowMaps = r.stats.cascades = r.stats.shadowMapSize = 0;
  if (bakedSplit || receiverSplit) r.drawShadows(frame, aspect, height, drawReceivers, bakedExtra, receiverExtra);
  const glm::dmat4 view = glm::inverse(camera.cameraToWorld);
  double orthoFar = 1.0;
  for (int i = 0; i < 8; ++i) {
    const glm::dvec3 corner(i & 1 ? r.boundsMax.x : r.boundsMin.x, i & 2 ? r.boundsMax.y : r.boundsMin.y,
                            i & 4 ? r.boundsMax.z : r.boundsMin.z);
    orthoFar = std::max(orthoFar, -(view * glm::dvec4(corner, 1.0)).z * 1.01 + camera.znear);
  }
  // Receivers may move outside the rest-pose bounds: extend the orthographic far plane.
  const glm::mat4 viewProj(projection(camera, aspect, 4.0 * orthoFar) * view);
  const glm::mat4 identity(1.0f);

  gl.BindFramebuffer(GL_FRAMEBUFFER, r.fbo);
  gl.Viewport(0, 0, width, height);
  gl.ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  gl.Enable(GL_DEPTH_TEST);
  gl.DepthFunc(GL_GREATER);
  const float black[4] = {0, 0, 0, 0};
  const float farDepth = 0.0f;
  gl.ClearNamedFramebufferfv(r.fbo, GL_COLOR, 0, black);
  gl.ClearNamedFramebufferfv(r.fbo, GL_DEPTH, 0, &farDepth);

  auto draw = [&](const Impl::Program& p, const Impl::Instance& in, bool mirrored) {
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
    if (!flat) {
      gl.ProgramUniform4fv(p.id, p.baseColor, 1, &in.baseColor.x);
      gl.ProgramUniform1f(p.id, p.opacity, in.opacity);
      if (p.alphaCutoff >= 0) gl.ProgramUniform1f(p.id, p.alphaCutoff, in.alphaCutoff);
      if (in.texture) gl.BindTextureUnit(0, in.texture);
      if (in.transmissionTexture) gl.BindTextureUnit(kTransmissionUnit, in.transmissionTexture);
    }
    gl.BindVertexArray(in.vao);
    gl.DrawElements(GL_TRIANGLES, in.indexCount, GL_UNSIGNED_INT, nullptr);
  };
  // Draws `list` grouped by program: each material variant's, or the flat one for all.
  // `place(program, instance)` sets the instance's own uniforms and returns whether its motion
  // mirrors it. `blended`: the instances drawn blended (Instance::blend), else the others; flat
  // shading draws every instance opaque.
  auto drawAll = [&](const std::vector<Impl::Instance>& list, const std::array<Impl::Program, kVariants>& programs,
                     auto&& place, int extra, bool blended = false) {
    for (int variant = 0; variant < (flat ? 1 : kVariants); ++variant) {
      const Impl::Program& p = flat ? r.flatProgram : programs[size_t(variant)];
      bool used = false;
      for (const Impl::Instance& in : list) {
        if (!flat && (in.variant | extra) != variant) continue;
        if (flat ? blended : in.blend != blended) continue;
        if (!used) {
          gl.UseProgram(p.id);
          gl.ProgramUniformMatrix4fv(p.id, p.viewProj, 1, GL_FALSE, &viewProj[0][0]);
          if (flat) gl.ProgramUniformMatrix4fv(p.id, p.model, 1, GL_FALSE, &identity[0][0]);
          used = true;
        }
        draw(p, in, place(p, in));
        r.stats.triangles += in.triangles;
      }
    }
  };

  r.stats.triangles = r.stats.receiverTriangles = 0;
  auto placeBaked = [&](const Impl::Program&, const Impl::Instance& in) {
    if (!flat && r.bands > kMaxAttributeBands) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, in.buffers[4]);
    if (!flat && in.backTransfer) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, in.backTransfer);
    if (!flat && bakedSplit) {
      gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, in.directTransfer[0]);
      if (in.directTransfer[1]) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, in.directTransfer[1]);
      gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, in.directBounce[0]);
      if (in.directBounce[1]) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, in.directBounce[1]);
    }
    return false;
  };
  if (!flat && (bakedSplit || receiverSplit) && r.shadowTexture) gl.BindTextureUnit(kShadowMapUnit, r.shadowTexture);
  drawAll(r.instances, r.programs, placeBaked, bakedExtra);
  auto placeReceiver = [&](const Impl::Program& p, const Impl::Instance& in) {
    const glm::dmat4 motion = instanceMotion(r.animation, in.placement, frame.time);
    const glm::dmat3 linear(motion);
    // Cofactor matrix = det · inverse transpose: maps normals, defined even for singular
    // motions; its scale does not matter (the shader normalises), its sign does.
    glm::dmat3 cof(glm::cross(linear[1], linear[2]), glm::cross(linear[2], linear[0]),
                   glm::cross(linear[0], linear[1]));
    const bool mirrored = glm::determinant(linear) < 0.0;
    if (mirrored) cof = -cof;
    const glm::mat4 model(motion);
    const glm::mat3 normalMatrix(cof);
    gl.ProgramUniformMatrix4fv(p.id, p.model, 1, GL_FALSE, &model[0][0]);
    if (!flat) gl.ProgramUniformMatrix3fv(p.id, p.normalMatrix, 1, GL_FALSE, &normalMatrix[0][0]);
    r.stats.receiverTriangles += in.triangles;
    return mirrored;
  };
  if (drawReceivers) {
    // Drawn after the baked instances, so that the depth test rejects hidden receiver pixels
    // before their (costly) probe lookup runs.
    if (!flat)
      for (GLuint unit = 1; unit <= 3; ++unit) gl.BindTextureUnit(unit, r.probeTextures[unit - 1]);
    drawAll(r.receivers, r.receiverPrograms[size_t(frame.probeLookup)], placeReceiver, receiverExtra);
  }
  if (!flat && frame.background) r.drawBackground(*frame.background, camera, width, height);
  if (!flat) {
    // BLEND and transmissive instances last, over the opaque ones and the background: "over"
    // blending (src·α + dst·(1 − α)), depth tested against the opaque depth but not written,
    // back to front by the view depth of each instance's bounding-box centre (a receiver's as
    // it moves): exact for layers that do not interleave, approximate where two overlap in
    // depth (no per-triangle sort).
    struct Layer {
      const Impl::Instance* in;
      bool receiver;
      double depth;
    };
    std::vector<Layer> layers;
    const glm::dvec3 eye(camera.cameraToWorld[3]), forward(-glm::dvec3(camera.cameraToWorld[2]));
    for (const Impl::Instance& in : r.instances)
      if (in.blend) layers.push_back({&in, false, glm::dot(0.5 * (in.restLo + in.restHi) - eye, forward)});
    if (drawReceivers)
      for (const Impl::Instance& in : r.receivers) {
        if (!in.blend) continue;
        const glm::dvec3 c = glm::dvec3(instanceMotion(r.animation, in.placement, frame.time) *
                                        glm::dvec4(0.5 * (in.restLo + in.restHi), 1.0));
        layers.push_back({&in, true, glm::dot(c - eye, forward)});
      }
    std::stable_sort(layers.begin(), layers.end(), [](const Layer& a, const Layer& b) { return a.depth > b.depth; });
    gl.Enable(GL_BLEND);
    gl.BlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    gl.DepthMask(GL_FALSE);
    if (drawReceivers)
      for (GLuint unit = 1; unit <= 3; ++unit) gl.BindTextureUnit(unit, r.probeTextures[unit - 1]);
    for (const Layer& layer : layers) {
      const Impl::Instance& in = *layer.in;
      const Impl::Program& p = layer.receiver ? r.receiverProgram(frame.probeLookup, in.variant | receiverExtra)
                                              : r.bakedProgram(in.variant | bakedExtra);
      gl.UseProgram(p.id);
      gl.ProgramUniformMatrix4fv(p.id, p.viewProj, 1, GL_FALSE, &viewProj[0][0]);
      draw(p, in, layer.receiver ? placeReceiver(p, in) : placeBaked(p, in));
      r.stats.triangles += in.triangles;
    }
    gl.DepthMask(GL_TRUE);
    gl.Disable(GL_BLEND);
  }
  gl.BindVertexArray(0);
  gl.Finish();
  r.checkError("drawing the frame");
  r.stats.drawMs = msSince(t1);

  const auto t2 = std::chrono::steady_clock::now();
  r.readback.resize(size_t(width) * height);
  if (r.resolveFbo) {
    // The average of each pixel's samples (a box filter over the pixel).
    gl.BlitNamedFramebuffer(r.fbo, r.resolveFbo, 0, 0, width, height, 0, 0, width, height, GL_COLOR_BUFFER_BIT,
                            GL_NEAREST);
    gl.BindFramebuffer(GL_FRAMEBUFFER, r.resolveFbo);
  }
  gl.PixelStorei(GL_PACK_ALIGNMENT, 4);
  gl.ReadPixels(0, 0, width, height, GL_RGBA, GL_FLOAT, r.readback.data());
  r.checkError("reading the frame back");
  gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
  ImageRgb image(width, height);
  for (int y = 0; y < height; ++y) {  // GL's row 0 is the bottom
    const glm::vec4* src = r.readback.data() + size_t(height - 1 - y) * width;
    for (int x = 0; x < width; ++x) image.at(x, y) = glm::vec3(src[x]);
  }
  r.stats.readbackMs = msSince(t2);
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
