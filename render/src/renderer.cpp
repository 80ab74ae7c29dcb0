// Rasterizing baked instances with per-vertex SH transfer (docs/render.md).
#include "prt/render/renderer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "gl_functions.h"
#include "prt/error.h"

namespace prt::render {

namespace {

// The vertex shader computes e = transfer · light. Two ways to reach a vertex's 3n² transfer
// floats, chosen by band count (measured on llvmpipe, 100k triangles at 256×256, 3 bands:
// attributes ≈ 15 ms a frame, SSBO ≈ 40 ms; llvmpipe fetches attributes in bulk but gathers
// SSBO loads lane by lane):
// - n <= kMaxAttributeBands: vertex attributes. 3n² <= 48 floats = 12 vec4 attributes, which
//   with position, texcoord and colour fits the 16 attributes every GL 4.5 offers. The flat
//   float sequence (coefficient i, channel c at 3i + c) is read as vec4 chunks; chunk k starts
//   at channel (4k) mod 3, so chunks k ≡ 0, 1, 2 (mod 3) hold (r g b r), (g b r g), (b r g b)
//   and three accumulators sorted by k mod 3 give the channels at the end. The light comes in
//   the same flat layout, zero-padded, so padding contributes nothing.
// - larger n: an SSBO holding the instance's transfer vertex-major ((v·n² + i)·3 + c) indexed
//   by gl_VertexID (glDrawElements without a base vertex makes it the index value); up to
//   192 floats per vertex, beyond any attribute budget.
constexpr int kMaxAttributeBands = 4;
constexpr GLuint kFirstTransferAttribute = 3;

int attributeChunks(int bands) { return (3 * bands * bands + 3) / 4; }

std::string vertexShader(int bands) {
  std::string s = R"(#version 450 core
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec2 aTexcoord;
layout(location = 2) in vec4 aColor;
uniform mat4 uViewProj;
out vec3 vTransferLight;
out vec2 vTexcoord;
out vec4 vColor;
)";
  if (bands <= kMaxAttributeBands) {
    const int chunks = attributeChunks(bands);
    for (int k = 0; k < chunks; ++k)
      s += cat("layout(location = ", kFirstTransferAttribute + k, ") in vec4 aTransfer", k, ";\n");
    s += cat("uniform vec4 uLightFlat[", chunks, "];\n");
    s += "void main() {\n  vec4 a[3] = vec4[3](vec4(0.0), vec4(0.0), vec4(0.0));\n";
    for (int k = 0; k < chunks; ++k)
      s += cat("  a[", k % 3, "] += aTransfer", k, " * uLightFlat[", k, "];\n");
    s += "  vTransferLight = vec3(a[0].x + a[0].w + a[1].z + a[2].y,\n"
         "                        a[0].y + a[1].x + a[1].w + a[2].z,\n"
         "                        a[0].z + a[1].y + a[2].x + a[2].w);\n";
  } else {
    s += cat("const int kCoeffs = ", bands * bands, ";\n");
    s += R"(layout(std430, binding = 0) readonly buffer Transfer { float transfer[]; };
uniform vec3 uLight[kCoeffs];
void main() {
  uint base = uint(gl_VertexID) * uint(kCoeffs * 3);
  vec3 e = vec3(0.0);
  for (int i = 0; i < kCoeffs; ++i) {
    uint k = base + uint(i * 3);
    e += vec3(transfer[k], transfer[k + 1u], transfer[k + 2u]) * uLight[i];
  }
  vTransferLight = e;
)";
  }
  s += R"(  vTexcoord = aTexcoord;
  vColor = aColor;
  gl_Position = uViewProj * vec4(aPosition, 1.0);
}
)";
  return s;
}

// Albedo per pixel: baseColorFactor × texture(texcoord) × COLOR_0; alpha is ignored.
constexpr const char* kFragmentShader = R"(#version 450 core
in vec3 vTransferLight;
in vec2 vTexcoord;
in vec4 vColor;
layout(binding = 0) uniform sampler2D uBaseColorTexture;
uniform vec4 uBaseColor;
uniform int uHasTexture;
uniform int uHasColor;
out vec4 fragColor;
void main() {
  vec3 albedo = uBaseColor.rgb;
  if (uHasColor != 0) albedo *= vColor.rgb;
  if (uHasTexture != 0) albedo *= texture(uBaseColorTexture, vTexcoord).rgb;
  fragColor = vec4(albedo * vTransferLight * 0.31830988618379067, 1.0);
}
)";

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

CameraView orbitView(const Scene& scene, const OrbitCamera& orbit, double aspect) {
  const glm::dvec3 lo(scene.boundsMin), hi(scene.boundsMax);
  const glm::dvec3 target = orbit.target ? glm::dvec3(*orbit.target) : 0.5 * (lo + hi);
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
    GLuint buffers[5] = {};  // positions, texcoords, colours, indices, transfer
    GLsizei indexCount = 0;
    glm::vec4 baseColor{1.0f};
    GLuint texture = 0;
    bool hasColor = false;
    bool doubleSided = false;
    bool mirrored = false;  // negative determinant: glTF flips the winding
  };

  GlContext& context;
  const GlFunctions& gl;
  int bands = 0;
  glm::vec3 boundsMin{0.0f}, boundsMax{0.0f};
  std::vector<Instance> instances;
  std::vector<GLuint> textures;  // per Scene texture, 0 where unused
  GLuint program = 0;
  GLint locViewProj = -1, locLight = -1, locBaseColor = -1, locHasTexture = -1,
        locHasColor = -1;
  GLuint fbo = 0, colorRb = 0, depthRb = 0;
  int fboWidth = 0, fboHeight = 0;
  std::vector<glm::vec4> readback;
  FrameStats stats;
  std::vector<std::string> warnings;

  Impl(GlContext& c) : context(c), gl(c.gl()) {}
  void checkError(const char* where) const;
  GLuint compile(GLenum type, const char* source, const char* what) const;
  void buildProgram();
  GLuint uploadTexture(const Texture& t);
  void upload(const Scene& scene);
  void ensureFramebuffer(int width, int height);
  void release();
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

void Renderer::Impl::buildProgram() {
  const std::string vsSource = vertexShader(bands);
  GLuint vs = compile(GL_VERTEX_SHADER, vsSource.c_str(), "vertex");
  GLuint fs = compile(GL_FRAGMENT_SHADER, kFragmentShader, "fragment");
  program = gl.CreateProgram();
  gl.AttachShader(program, vs);
  gl.AttachShader(program, fs);
  gl.LinkProgram(program);
  gl.DeleteShader(vs);
  gl.DeleteShader(fs);
  GLint ok = 0;
  gl.GetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    gl.GetProgramInfoLog(program, sizeof log, nullptr, log);
    throw Error(cat("GL: shader program does not link: ", log));
  }
  locViewProj = gl.GetUniformLocation(program, "uViewProj");
  locLight = gl.GetUniformLocation(program, bands <= kMaxAttributeBands ? "uLightFlat" : "uLight");
  locBaseColor = gl.GetUniformLocation(program, "uBaseColor");
  locHasTexture = gl.GetUniformLocation(program, "uHasTexture");
  locHasColor = gl.GetUniformLocation(program, "uHasColor");
}

GLuint Renderer::Impl::uploadTexture(const Texture& t) {
  GLuint tex = 0;
  gl.CreateTextures(GL_TEXTURE_2D, 1, &tex);
  // Texels are already linear (sRGB-decoded by the loader), so a float texture keeps them
  // exact; row 0 (v = 0) goes to t = 0, which is where glTF's v = 0 samples it.
  gl.TextureStorage2D(tex, 1, GL_RGBA32F, t.width, t.height);
  gl.PixelStorei(GL_UNPACK_ALIGNMENT, 4);
  gl.TextureSubImage2D(tex, 0, 0, 0, t.width, t.height, GL_RGBA, GL_FLOAT, t.texels.data());
  gl.TextureParameteri(tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  gl.TextureParameteri(tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  gl.TextureParameteri(tex, GL_TEXTURE_WRAP_S, wrapMode(t.wrapS));
  gl.TextureParameteri(tex, GL_TEXTURE_WRAP_T, wrapMode(t.wrapT));
  checkError(cat("uploading texture '", t.name, "'").c_str());
  return tex;
}

void Renderer::Impl::upload(const Scene& scene) {
  boundsMin = scene.boundsMin;
  boundsMax = scene.boundsMax;
  const size_t n2 = size_t(bands) * bands;
  GLint maxSsbo = 0;
  gl.GetIntegerv(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &maxSsbo);
  textures.assign(scene.textures.size(), 0);

  for (const MeshInstance& m : scene.meshes) {
    if (m.receiverOnly || m.transferBands == 0) {
      warnings.push_back(cat("skipping ", m.receiverOnly ? "receiver-only" : "unbaked",
                             " instance '", m.name, "': no transfer (receivers are not drawn yet)"));
      continue;
    }
    if (m.transferBands != bands || m.transfer.size() != m.vertexCount() * n2)
      throw Error(cat(scene.path, ": instance '", m.name, "': transfer holds ", m.transfer.size(),
                      " values of ", m.transferBands, " bands, expected ", m.vertexCount() * n2,
                      " of ", bands));
    const size_t transferBytes = m.transfer.size() * sizeof(glm::vec3);
    if (bands > kMaxAttributeBands && transferBytes > size_t(maxSsbo))
      throw Error(cat(scene.path, ": instance '", m.name, "': transfer of ", transferBytes >> 20,
                      " MiB exceeds the GL's shader storage block limit of ", maxSsbo >> 20, " MiB"));

    Instance in;
    in.indexCount = GLsizei(m.indices.size());
    in.hasColor = !m.colors.empty();
    in.mirrored = glm::determinant(glm::dmat3(m.world)) < 0.0;
    if (m.material >= 0) {
      const Material& mat = scene.materials.at(size_t(m.material));
      in.baseColor = mat.baseColorFactor;
      in.doubleSided = mat.doubleSided;
      if (mat.baseColorTexture >= 0 && !m.texcoords.empty()) {
        GLuint& tex = textures.at(size_t(mat.baseColorTexture));
        if (!tex) tex = uploadTexture(scene.textures[size_t(mat.baseColorTexture)]);
        in.texture = tex;
      }
    }

    gl.CreateBuffers(5, in.buffers);
    auto store = [&](GLuint buffer, const auto& v) {
      // Empty buffers are still created, with one byte: a zero-size store is an error.
      const size_t bytes = v.size() * sizeof(v[0]);
      gl.NamedBufferStorage(buffer, GLsizeiptr(std::max<size_t>(bytes, 1)),
                            bytes ? v.data() : nullptr, 0);
    };
    store(in.buffers[0], m.positions);
    store(in.buffers[1], m.texcoords);
    store(in.buffers[2], m.colors);
    store(in.buffers[3], m.indices);
    store(in.buffers[4], m.transfer);

    gl.CreateVertexArrays(1, &in.vao);
    auto attribute = [&](GLuint location, GLuint buffer, GLint components, bool present) {
      if (!present) return;  // the shader ignores it (uHasColor) or the texture is not sampled
      gl.VertexArrayVertexBuffer(in.vao, location, buffer, 0, GLsizei(components * sizeof(float)));
      gl.VertexArrayAttribFormat(in.vao, location, components, GL_FLOAT, GL_FALSE, 0);
      gl.VertexArrayAttribBinding(in.vao, location, location);
      gl.EnableVertexArrayAttrib(in.vao, location);
    };
    attribute(0, in.buffers[0], 3, true);
    attribute(1, in.buffers[1], 2, !m.texcoords.empty());
    attribute(2, in.buffers[2], 4, in.hasColor);
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
    stats.triangles += m.triangleCount();
  }
  if (instances.empty())
    throw Error(cat(scene.path, ": no baked instance to render"));
}

void Renderer::Impl::ensureFramebuffer(int width, int height) {
  if (fbo && width == fboWidth && height == fboHeight) return;
  GLint maxSize = 0;
  gl.GetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &maxSize);
  if (width <= 0 || height <= 0 || width > maxSize || height > maxSize)
    throw Error(cat("render: frame size ", width, "x", height, " outside 1..", maxSize));
  if (fbo) {
    gl.DeleteFramebuffers(1, &fbo);
    gl.DeleteRenderbuffers(1, &colorRb);
    gl.DeleteRenderbuffers(1, &depthRb);
  }
  gl.CreateRenderbuffers(1, &colorRb);
  gl.NamedRenderbufferStorage(colorRb, GL_RGBA32F, width, height);
  gl.CreateRenderbuffers(1, &depthRb);
  gl.NamedRenderbufferStorage(depthRb, GL_DEPTH_COMPONENT32F, width, height);
  gl.CreateFramebuffers(1, &fbo);
  gl.NamedFramebufferRenderbuffer(fbo, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, colorRb);
  gl.NamedFramebufferRenderbuffer(fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depthRb);
  gl.NamedFramebufferDrawBuffer(fbo, GL_COLOR_ATTACHMENT0);
  gl.NamedFramebufferReadBuffer(fbo, GL_COLOR_ATTACHMENT0);
  const GLenum status = gl.CheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE)
    throw Error(cat("GL: RGBA32F framebuffer incomplete (", glErrorName(status), ")"));
  checkError("creating the framebuffer");
  fboWidth = width;
  fboHeight = height;
}

void Renderer::Impl::release() {
  for (Instance& in : instances) {
    gl.DeleteVertexArrays(1, &in.vao);
    gl.DeleteBuffers(5, in.buffers);
  }
  for (GLuint t : textures)
    if (t) gl.DeleteTextures(1, &t);
  if (program) gl.DeleteProgram(program);
  if (fbo) {
    gl.DeleteFramebuffers(1, &fbo);
    gl.DeleteRenderbuffers(1, &colorRb);
    gl.DeleteRenderbuffers(1, &depthRb);
  }
}

Renderer::Renderer(GlContext& context, const Scene& scene) : impl_(std::make_unique<Impl>(context)) {
  if (scene.transferBands <= 0 || scene.transferBands > sh::kMaxBands)
    throw Error(cat(scene.path, ": holds no baked transfer (run prt bake first)"));
  impl_->bands = scene.transferBands;
  context.makeCurrent();
  try {
    impl_->buildProgram();
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

ImageRgb Renderer::render(const CameraView& camera, const sh::ShRgb& light) {
  return render(camera, light, impl_->context.width(), impl_->context.height());
}

ImageRgb Renderer::render(const CameraView& camera, const sh::ShRgb& light, int width, int height) {
  Impl& r = *impl_;
  const GlFunctions& gl = r.gl;
  r.context.makeCurrent();
  const auto t0 = std::chrono::steady_clock::now();
  r.ensureFramebuffer(width, height);

  const double aspect = double(width) / height;
  const glm::dmat4 view = glm::inverse(camera.cameraToWorld);
  double orthoFar = 1.0;
  for (int i = 0; i < 8; ++i) {
    const glm::dvec3 corner(i & 1 ? r.boundsMax.x : r.boundsMin.x, i & 2 ? r.boundsMax.y : r.boundsMin.y,
                            i & 4 ? r.boundsMax.z : r.boundsMin.z);
    orthoFar = std::max(orthoFar, -(view * glm::dvec4(corner, 1.0)).z * 1.01 + camera.znear);
  }
  const glm::mat4 viewProj(projection(camera, aspect, orthoFar) * view);
  const sh::ShRgb l = sh::resize(light, r.bands);

  gl.BindFramebuffer(GL_FRAMEBUFFER, r.fbo);
  gl.Viewport(0, 0, width, height);
  gl.ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  gl.Enable(GL_DEPTH_TEST);
  gl.DepthFunc(GL_GREATER);
  const float black[4] = {0, 0, 0, 0};
  const float farDepth = 0.0f;
  gl.ClearNamedFramebufferfv(r.fbo, GL_COLOR, 0, black);
  gl.ClearNamedFramebufferfv(r.fbo, GL_DEPTH, 0, &farDepth);

  gl.UseProgram(r.program);
  gl.ProgramUniformMatrix4fv(r.program, r.locViewProj, 1, GL_FALSE, &viewProj[0][0]);
  if (r.bands <= kMaxAttributeBands) {
    std::vector<glm::vec4> flat(size_t(attributeChunks(r.bands)), glm::vec4(0.0f));
    for (int i = 0; i < l.size(); ++i)
      for (int c = 0; c < 3; ++c) flat[size_t(3 * i + c) / 4][(3 * i + c) % 4] = l.c[size_t(i)][c];
    gl.ProgramUniform4fv(r.program, r.locLight, GLsizei(flat.size()), &flat[0].x);
  } else {
    gl.ProgramUniform3fv(r.program, r.locLight, l.size(), &l.c[0].x);
  }
  for (const Impl::Instance& in : r.instances) {
    if (in.doubleSided) {
      gl.Disable(GL_CULL_FACE);
    } else {
      gl.Enable(GL_CULL_FACE);
      gl.CullFace(GL_BACK);
      gl.FrontFace(in.mirrored ? GL_CW : GL_CCW);
    }
    gl.ProgramUniform4fv(r.program, r.locBaseColor, 1, &in.baseColor.x);
    gl.ProgramUniform1i(r.program, r.locHasTexture, in.texture ? 1 : 0);
    gl.ProgramUniform1i(r.program, r.locHasColor, in.hasColor ? 1 : 0);
    if (in.texture) gl.BindTextureUnit(0, in.texture);
    if (r.bands > kMaxAttributeBands) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, in.buffers[4]);
    gl.BindVertexArray(in.vao);
    gl.DrawElements(GL_TRIANGLES, in.indexCount, GL_UNSIGNED_INT, nullptr);
  }
  gl.BindVertexArray(0);
  gl.Finish();
  r.checkError("drawing the frame");
  r.stats.drawMs = msSince(t0);

  const auto t1 = std::chrono::steady_clock::now();
  r.readback.resize(size_t(width) * height);
  gl.PixelStorei(GL_PACK_ALIGNMENT, 4);
  gl.ReadPixels(0, 0, width, height, GL_RGBA, GL_FLOAT, r.readback.data());
  r.checkError("reading the frame back");
  gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
  ImageRgb image(width, height);
  for (int y = 0; y < height; ++y) {  // GL's row 0 is the bottom
    const glm::vec4* src = r.readback.data() + size_t(height - 1 - y) * width;
    for (int x = 0; x < width; ++x) image.at(x, y) = glm::vec3(src[x]);
  }
  r.stats.readbackMs = msSince(t1);
  return image;
}

int Renderer::bands() const { return impl_->bands; }
const FrameStats& Renderer::lastFrame() const { return impl_->stats; }
const std::vector<std::string>& Renderer::warnings() const { return impl_->warnings; }

}  // namespace prt::render
