// The scene and the probe grid on the GPU: instances (buffers, vertex arrays, materials,
// textures), the probe grid's buffers, and the direct lights' per-frame bounce.
#include <algorithm>

#include "probe_shading.h"
#include "prt/error.h"
#include "renderer_impl.h"
#include "shader_sources.h"

namespace prt::render {

namespace {

// A buffer holding `v`. Empty buffers are still created, with one byte: a zero-size store is an
// error. `flags`: GL_DYNAMIC_STORAGE_BIT for a buffer rewritten per frame.
template <class Vector>
GlBuffer storeBuffer(const GlFunctions& gl, const Vector& v, GLbitfield flags = 0) {
  GlBuffer buffer = createBuffer(gl);
  const size_t bytes = v.size() * sizeof(v[0]);
  gl.NamedBufferStorage(buffer, GLsizeiptr(std::max<size_t>(bytes, 1)), bytes ? v.data() : nullptr, flags);
  return buffer;
}

// Attribute `location` from `buffer`, `components` floats a vertex; left disabled when not
// `present` (the shader variant does not read it, or reads it only where it is present).
void attribute(const GlFunctions& gl, GLuint vao, GLuint location, GLuint buffer, GLint components, bool present) {
  if (!present) return;
  gl.VertexArrayVertexBuffer(vao, location, buffer, 0, GLsizei(components * sizeof(float)));
  gl.VertexArrayAttribFormat(vao, location, components, GL_FLOAT, GL_FALSE, 0);
  gl.VertexArrayAttribBinding(vao, location, location);
  gl.EnableVertexArrayAttrib(vao, location);
}

// The transfer as kFirstTransferAttribute + k, k < attributeChunks(bands): vec4 chunks of the
// vertex's flat 3n² floats (shader_sources.h).
void transferAttributes(const GlFunctions& gl, GLuint vao, GLuint transfer, int bands) {
  const size_t n2 = size_t(bands) * bands;
  const GLsizei stride = GLsizei(n2 * sizeof(glm::vec3));
  gl.VertexArrayVertexBuffer(vao, kFirstTransferAttribute, transfer, 0, stride);
  const int floats = int(3 * n2);
  for (int k = 0; k < attributeChunks(bands); ++k) {
    // A last chunk of fewer than 4 floats reads w = 1, multiplied by the light's zero pad.
    const GLuint location = kFirstTransferAttribute + GLuint(k);
    gl.VertexArrayAttribFormat(vao, location, std::min(4, floats - 4 * k), GL_FLOAT, GL_FALSE, GLuint(16 * k));
    gl.VertexArrayAttribBinding(vao, location, kFirstTransferAttribute);
    gl.EnableVertexArrayAttrib(vao, location);
  }
}

void restBounds(const std::vector<glm::vec3>& positions, glm::dvec3& lo, glm::dvec3& hi) {
  lo = glm::dvec3(1e300);
  hi = glm::dvec3(-1e300);
  for (const glm::vec3& p : positions) {
    lo = glm::min(lo, glm::dvec3(p));
    hi = glm::max(hi, glm::dvec3(p));
  }
}

GLint wrapMode(int gltf) {
  // glTF stores the GL enums themselves.
  return gltf == GL_CLAMP_TO_EDGE || gltf == GL_MIRRORED_REPEAT ? gltf : GL_REPEAT;
}

// Which parts of a baked instance's transfer are drawn, checked against its vertex count.
struct TransferParts {
  bool twoSided = false;  // the back side's transfer (a double-sided material; a one-sided back is culled)
  bool direct = false;    // the direct part t⁰ on every side drawn, else the direct lights go through SH
};

TransferParts checkTransfer(const Scene& scene, const MeshInstance& m, int bands, GLint maxSsbo) {
  const size_t n2 = size_t(bands) * bands;
  if (m.transfer.size() != m.vertexCount() * n2)
    throw Error(cat(scene.path, ": instance '", m.name, "': transfer holds ", m.transfer.size(), " values, expected ",
                    m.vertexCount() * n2, " (", m.vertexCount(), " vertices, ", bands, " bands)"));
  TransferParts parts;
  parts.twoSided = m.hasBackTransfer() && m.material >= 0 && scene.materials.at(size_t(m.material)).doubleSided;
  if (parts.twoSided && m.transferBack.size() != m.transfer.size())
    throw Error(cat(scene.path, ": instance '", m.name, "': back-side transfer holds ", m.transferBack.size(),
                    " values, expected ", m.transfer.size()));
  const size_t transferBytes = m.transfer.size() * sizeof(glm::vec3);
  if ((bands > kMaxAttributeBands || parts.twoSided) && transferBytes > size_t(maxSsbo))
    throw Error(cat(scene.path, ": instance '", m.name, "': transfer of ", transferBytes >> 20,
                    " MiB exceeds the GL's shader storage block limit of ", maxSsbo >> 20, " MiB"));
  parts.direct = m.transferDirect.size() == m.vertexCount() * n2 &&
                 (!parts.twoSided || m.transferDirectBack.size() == m.vertexCount() * n2) &&
                 m.normals.size() == m.vertexCount();
  if (m.hasDirectTransfer() && !parts.direct)
    throw Error(cat(scene.path, ": instance '", m.name, "': direct transfer holds ", m.transferDirect.size(),
                    " values (back ", m.transferDirectBack.size(), "), expected ", m.vertexCount() * n2));
  return parts;
}

}  // namespace

GlTexture Renderer::Impl::linearFloatTexture(GLenum internalFormat, GLenum format, int width, int height,
                                             const void* texels, GLint wrapS, GLint wrapT) const {
  GlTexture tex = createTexture(gl, GL_TEXTURE_2D);
  gl.TextureStorage2D(tex, 1, internalFormat, width, height);
  gl.PixelStorei(GL_UNPACK_ALIGNMENT, 4);
  gl.TextureSubImage2D(tex, 0, 0, 0, width, height, format, GL_FLOAT, texels);
  gl.TextureParameteri(tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  gl.TextureParameteri(tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  gl.TextureParameteri(tex, GL_TEXTURE_WRAP_S, wrapS);
  gl.TextureParameteri(tex, GL_TEXTURE_WRAP_T, wrapT);
  return tex;
}

GLuint Renderer::Impl::sceneTexture(const Scene& scene, int index) {
  GlTexture& tex = textures.at(size_t(index));
  if (!tex) {
    // Texels are already linear (sRGB-decoded by the loader), so a float texture keeps them
    // exact; row 0 (v = 0) goes to t = 0, which is where glTF's v = 0 samples it.
    const Texture& t = scene.textures[size_t(index)];
    tex = linearFloatTexture(GL_RGBA32F, GL_RGBA, t.width, t.height, t.texels.data(), wrapMode(t.wrapS),
                             wrapMode(t.wrapT));
    checkError(cat("uploading texture '", t.name, "'").c_str());
  }
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
    in.texture = sceneTexture(scene, mat.baseColorTexture);
    in.variant |= kVariantTexture;
  }
  if (mat.transmissionFactor > 0.0f && mat.transmissionTexture >= 0 && !m.texcoords.empty()) {
    in.transmissionTexture = sceneTexture(scene, mat.transmissionTexture);
    in.variant |= kVariantTransmission;
  }
}

void Renderer::Impl::upload(const Scene& scene) {
  boundsMin = scene.boundsMin;
  boundsMax = scene.boundsMax;
  animation = scene;  // the SceneAnimation part only
  GLint maxSsbo = 0;
  gl.GetIntegerv(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &maxSsbo);
  textures.clear();
  textures.resize(scene.textures.size());
  for (const MeshInstance& m : scene.meshes) {
    if (m.receiverOnly)
      uploadReceiver(scene, m);
    else if (m.transfer.empty())
      warnings.push_back(cat("skipping unbaked instance '", m.name, "': no transfer and not a receiver"));
    else
      uploadBaked(scene, m, maxSsbo);
  }
  if (instances.empty() && receivers.empty()) throw Error(cat(scene.path, ": no baked instance or receiver to render"));
}

// A receiver, drawn from the probe grid: positions, normals, texcoords, colours; no transfer.
void Renderer::Impl::uploadReceiver(const Scene& scene, const MeshInstance& m) {
  Instance in;
  setMaterial(scene, m, in);
  in.placement.name = m.name;
  in.placement.node = m.node;
  in.placement.world = m.world;
  restBounds(m.positions, in.restLo, in.restHi);
  in.positions = storeBuffer(gl, m.positions);
  in.texcoords = storeBuffer(gl, m.texcoords);
  in.colors = storeBuffer(gl, m.colors);
  in.indices = storeBuffer(gl, m.indices);
  in.normals = storeBuffer(gl, m.normals);
  in.vao = createVertexArray(gl);
  attribute(gl, in.vao, 0, in.positions, 3, true);
  attribute(gl, in.vao, 1, in.texcoords, 2, !m.texcoords.empty());
  attribute(gl, in.vao, 2, in.colors, 4, in.hasColor);
  attribute(gl, in.vao, 3, in.normals, 3, m.normals.size() == m.positions.size());
  setFullMaterial(scene, m, in, true);
  gl.VertexArrayElementBuffer(in.vao, in.indices);
  checkError(cat("uploading receiver '", m.name, "'").c_str());
  receivers.push_back(std::move(in));
}

// A baked instance: its vertices, its transfer (front, back, direct parts) and the direct
// lights' bounce buffers (zeros until a frame gives one).
void Renderer::Impl::uploadBaked(const Scene& scene, const MeshInstance& m, GLint maxSsbo) {
  const TransferParts parts = checkTransfer(scene, m, bands, maxSsbo);
  bakedDirect = (instances.empty() || bakedDirect) && parts.direct;
  Instance in;
  setMaterial(scene, m, in);
  if (parts.twoSided) in.variant |= kVariantTwoSided;
  bakedProgram(in.variant);
  in.positions = storeBuffer(gl, m.positions);
  in.texcoords = storeBuffer(gl, m.texcoords);
  in.colors = storeBuffer(gl, m.colors);
  in.indices = storeBuffer(gl, m.indices);
  in.transfer = storeBuffer(gl, m.transfer);
  // The normals serve the direct lights (DIRECT) and the material (MATERIAL).
  const bool normals = m.normals.size() == m.vertexCount();
  in.normals = storeBuffer(gl, normals ? m.normals : std::vector<glm::vec3>());
  if (parts.twoSided) in.transferBack = storeBuffer(gl, m.transferBack);
  in.mesh = size_t(&m - scene.meshes.data());
  in.vertices = m.vertexCount();
  restBounds(m.positions, in.restLo, in.restHi);
  if (parts.direct) {
    const std::vector<glm::vec3> zeros(m.vertexCount(), glm::vec3(0.0f));
    in.transferDirect = storeBuffer(gl, m.transferDirect);
    in.directBounce = storeBuffer(gl, zeros, GL_DYNAMIC_STORAGE_BIT);
    if (parts.twoSided) {
      in.transferDirectBack = storeBuffer(gl, m.transferDirectBack);
      in.directBounceBack = storeBuffer(gl, zeros, GL_DYNAMIC_STORAGE_BIT);
    }
  }
  in.vao = createVertexArray(gl);
  attribute(gl, in.vao, 0, in.positions, 3, true);
  attribute(gl, in.vao, 1, in.texcoords, 2, !m.texcoords.empty());
  attribute(gl, in.vao, 2, in.colors, 4, in.hasColor);
  attribute(gl, in.vao, kNormalAttribute, in.normals, 3, normals);
  if (bands <= kMaxAttributeBands) transferAttributes(gl, in.vao, in.transfer, bands);
  setFullMaterial(scene, m, in, false);
  gl.VertexArrayElementBuffer(in.vao, in.indices);
  checkError(cat("uploading instance '", m.name, "'").c_str());
  instances.push_back(std::move(in));
}

void Renderer::Impl::releaseProbes() {
  probes = ProbeBuffers{};
  for (auto& lookup : receiverPrograms)
    for (Program& p : lookup) p = Program{};
  grid = nullptr;
}

void Renderer::Impl::uploadProbes(const ProbeGrid& g) {
  if (g.bands < 1 || g.bands > sh::kMaxBands)
    throw Error(cat("probe grid: ", g.bands, " bands, expected 1..", sh::kMaxBands));
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
  probes.lattice = storeBuffer(gl, lattice);
  probes.statics = storeBuffer(gl, statics);
  probes.radiance = createBuffer(gl);
  gl.NamedBufferStorage(probes.radiance, GLsizeiptr(radianceCount * sizeof(glm::vec4)), nullptr,
                        GL_DYNAMIC_STORAGE_BIT);
  auto bufferTexture = [&](GLenum format, GLuint buffer) {
    GlTexture t = createTexture(gl, GL_TEXTURE_BUFFER);
    gl.TextureBuffer(t, format, buffer);
    return t;
  };
  probes.latticeTexture = bufferTexture(GL_R32I, probes.lattice);
  probes.staticTexture = bufferTexture(GL_RGBA32F, probes.statics);
  probes.radianceTexture = bufferTexture(GL_RGBA32F, probes.radiance);
  checkError("uploading the probe grid");
}

// The direct lights' gathered bounce into each baked instance's bounce buffers (zeros where the
// frame gives none, written once until a bounce comes again).
void Renderer::Impl::uploadBounce(const std::vector<std::vector<glm::vec3>>* front,
                                  const std::vector<std::vector<glm::vec3>>* back) {
  for (Instance& in : instances) {
    if (!in.directBounce) continue;
    if (!front && in.bounceZero) continue;
    const std::vector<glm::vec3> zeros(front ? 0 : in.vertices, glm::vec3(0.0f));
    for (int side = 0; side < 2; ++side) {
      const GLuint buffer = side ? in.directBounceBack : in.directBounce;
      if (!buffer) continue;
      const std::vector<std::vector<glm::vec3>>* given = side ? back : front;
      const std::vector<glm::vec3>* v = &zeros;
      if (given) {
        if (given->size() <= in.mesh || (*given)[in.mesh].size() != in.vertices)
          throw Error(cat("render: the direct lights' bounce holds ",
                          given->size() > in.mesh ? (*given)[in.mesh].size() : 0, " values for instance ", in.mesh,
                          (side ? " (back side)" : ""), ", expected ", in.vertices));
        v = &(*given)[in.mesh];
      }
      if (!v->empty()) gl.NamedBufferSubData(buffer, 0, GLsizeiptr(v->size() * sizeof(glm::vec3)), v->data());
    }
    in.bounceZero = front == nullptr;
  }
}

}  // namespace prt::render
