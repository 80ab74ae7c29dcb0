// Material lookups: bilinear texture sampling with the glTF wrap modes, and the bake's diffuse
// albedo, alpha and opacity at a vertex or at a point of a triangle.
#include "prt/scene.h"

#include <algorithm>
#include <cmath>

#include "prt/brdf.h"
#include "prt/error.h"

namespace prt {

namespace {

// Texture::sample, inlined where this file samples (albedoAt, alphaAt): called, its vec4 came
// back through the stack, read back in halves before the store had landed, and that stall was a
// fifth of a lookup.
inline __attribute__((always_inline)) glm::vec4 sampleTexture(const Texture& t, const glm::vec2& uv) {
  const int width = t.width, height = t.height, wrapS = t.wrapS, wrapT = t.wrapT;
  const std::vector<glm::vec4>& texels = t.texels;
  const std::vector<uint32_t>& texels8 = t.texels8;
  const std::array<std::array<float, 256>, 2>& levels8 = t.levels8;
  if (width <= 0 || height <= 0 || texels.empty()) return glm::vec4(1.0f);
  // Texel i covers [i, i+1)/w, its centre at (i+0.5)/w; x is in texel units from the first centre.
  auto wrap = [](double i, int n, int mode) -> int {
    if (mode == Texture::kClampToEdge) return static_cast<int>(std::clamp(i, 0.0, double(n - 1)));
    if (mode == Texture::kMirroredRepeat) {
      double m = i - 2.0 * n * std::floor(i / (2.0 * n));  // in [0, 2n)
      return static_cast<int>(m < n ? m : 2.0 * n - 1.0 - m);
    }
    return static_cast<int>(i - n * std::floor(i / n));  // REPEAT
  };
  auto axis = [&](float coord, int n, int mode, int& i0, int& i1, double& f) {
    double x = std::isfinite(coord) ? std::clamp(double(coord), -1e6, 1e6) * n - 0.5 : 0.0;
    double x0 = std::floor(x);
    f = x - x0;
    if (x0 >= 0.0 && x0 + 1.0 <= double(n - 1)) {  // both texels inside: every mode keeps them as they are
      i0 = int(x0);
      i1 = i0 + 1;
      return;
    }
    i0 = std::clamp(wrap(x0, n, mode), 0, n - 1);
    i1 = std::clamp(wrap(x0 + 1.0, n, mode), 0, n - 1);
  };
  int x0, x1, y0, y1;
  double fx, fy;
  axis(uv.x, width, wrapS, x0, x1, fx);
  axis(uv.y, height, wrapT, y0, y1, fy);
  auto filter = [&](auto at) {
    glm::dvec4 top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
    glm::dvec4 bottom = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
    return glm::vec4(top * (1.0 - fy) + bottom * fy);
  };
  if (texels8.size() == texels.size()) {  // the same values from a quarter of the bytes
    return filter([&](int x, int y) {
      const uint32_t p = texels8[size_t(y) * size_t(width) + size_t(x)];
      const std::array<float, 256>& c = levels8[0];
      return glm::dvec4(c[p & 255u], c[(p >> 8) & 255u], c[(p >> 16) & 255u], levels8[1][p >> 24]);
    });
  }
  return filter([&](int x, int y) { return glm::dvec4(texels[size_t(y) * size_t(width) + size_t(x)]); });
}

}  // namespace

glm::vec4 Texture::sample(const glm::vec2& uv) const { return sampleTexture(*this, uv); }

float diffuseScale(const Scene& scene, const MeshInstance& mesh) {
  if (mesh.material < 0) return 1.0f;
  const Material& m = scene.materials[size_t(mesh.material)];
  if (m.specularGlossiness || m.unlit) return 1.0f;
  // The dielectric's specular share relative to the default dielectric's (docs/bake.md,
  // "Materials"): exactly 1 for ior 1.5 without KHR_materials_specular, so such materials keep
  // the base colour's bits.
  float dielectric = 1.0f;
  if (m.ior != 1.5f || m.specularFactor != 1.0f || m.specularColorFactor != glm::vec3(1.0f)) {
    static const double kDefault = brdf::dielectricDiffuseWeight(1.5, 1.0, glm::dvec3(1.0));
    const double w = brdf::dielectricDiffuseWeight(m.ior, m.specularFactor, glm::dvec3(m.specularColorFactor));
    dielectric = static_cast<float>(std::min(1.0, w / kDefault));
  }
  return readsMetallicTexture(scene, mesh) ? dielectric : (1.0f - m.metallicFactor) * dielectric;
}

bool readsMetallicTexture(const Scene& scene, const MeshInstance& mesh) {
  if (mesh.material < 0) return false;
  const Material& m = scene.materials[size_t(mesh.material)];
  return !m.specularGlossiness && !m.unlit && m.metallicRoughnessTexture.texture >= 0 &&
         !mesh.uvs(m.metallicRoughnessTexture.uvSet).empty();
}

namespace {

// The albedo at a point, given how to read a texture coordinate set and COLOR_0 there.
// `bounce` adds the metal's specular lobe as the bake bounces it (docs/bake.md, "Materials"):
// metallic × (baseColor · Ā + B̄), (Ā, B̄) = brdf::cosineAveragedDfg(roughness). The diffuse
// part is computed in the order it always was, so materials without metal keep their bits.
template <class Uv, class Colour>
glm::vec3 albedoWith(const Scene& scene, const MeshInstance& mesh, bool bounce, Uv&& uv, Colour&& colour) {
  glm::vec3 albedo(1.0f), base(1.0f);
  float metallic = 0.0f, roughness = 1.0f;
  if (mesh.material >= 0) {
    const Material& mat = scene.materials[size_t(mesh.material)];
    albedo = glm::vec3(mat.baseColorFactor) * diffuseScale(scene, mesh);
    base = glm::vec3(mat.baseColorFactor);
    if (mat.baseColorTexture >= 0 && !mesh.texcoords.empty()) {
      const glm::vec3 texel(sampleTexture(scene.textures[size_t(mat.baseColorTexture)], uv(mesh.texcoords)));
      albedo *= texel;
      base *= texel;
    }
    if (!mat.specularGlossiness && !mat.unlit) {
      metallic = mat.metallicFactor;
      roughness = mat.roughnessFactor;
    }
    if (readsMetallicTexture(scene, mesh)) {  // metallic = factor × B, roughness = factor × G
      const TextureSlot& mr = mat.metallicRoughnessTexture;
      const glm::vec4 texel = sampleTexture(scene.textures[size_t(mr.texture)], uv(mesh.uvs(mr.uvSet)));
      albedo *= 1.0f - mat.metallicFactor * texel.b;
      metallic *= texel.b;
      roughness *= texel.g;
    }
  }
  if (!mesh.colors.empty()) {
    const glm::vec3 c(colour());
    albedo *= c;
    base *= c;
  }
  if (bounce && metallic > 0.0f) {
    const glm::vec2 ab(brdf::cosineAveragedDfg(roughness));
    albedo += metallic * (base * ab.x + ab.y);
  }
  return albedo;
}

glm::vec3 atVertex(const Scene& scene, const MeshInstance& mesh, uint32_t v, bool bounce) {
  PRT_CHECK_LT(size_t(v), mesh.vertexCount());
  return albedoWith(
      scene, mesh, bounce, [&](const std::vector<glm::vec2>& t) { return t[v]; }, [&] { return mesh.colors[v]; });
}

}  // namespace

glm::vec3 albedoAtVertex(const Scene& scene, const MeshInstance& mesh, uint32_t v) {
  return atVertex(scene, mesh, v, true);
}

glm::vec3 diffuseAlbedoAtVertex(const Scene& scene, const MeshInstance& mesh, uint32_t v) {
  return atVertex(scene, mesh, v, false);
}

glm::vec3 albedoAt(const Scene& scene, const MeshInstance& mesh, uint32_t tri, float b1, float b2) {
  PRT_CHECK_LT(size_t(tri), mesh.triangleCount());
  const uint32_t* i = &mesh.indices[3 * size_t(tri)];
  const float b0 = 1.0f - b1 - b2;
  // Interpolate the coordinates, not the texels: the texture varies inside the triangle.
  return albedoWith(
      scene, mesh, true, [&](const std::vector<glm::vec2>& t) { return b0 * t[i[0]] + b1 * t[i[1]] + b2 * t[i[2]]; },
      [&] { return b0 * mesh.colors[i[0]] + b1 * mesh.colors[i[1]] + b2 * mesh.colors[i[2]]; });
}

bool bouncesSpecular(const Scene& scene, const MeshInstance& mesh) {
  if (mesh.material < 0) return false;
  const Material& m = scene.materials[size_t(mesh.material)];
  return !m.specularGlossiness && !m.unlit && m.metallicFactor > 0.0f;
}

float alphaAt(const Scene& scene, const MeshInstance& mesh, uint32_t tri, float b1, float b2) {
  PRT_CHECK_LT(size_t(tri), mesh.triangleCount());
  const uint32_t* i = &mesh.indices[3 * size_t(tri)];
  const float b0 = 1.0f - b1 - b2;
  float alpha = 1.0f;
  if (mesh.material >= 0) {
    const Material& mat = scene.materials[size_t(mesh.material)];
    alpha = mat.baseColorFactor.a;
    if (mat.baseColorTexture >= 0 && !mesh.texcoords.empty()) {
      glm::vec2 uv = b0 * mesh.texcoords[i[0]] + b1 * mesh.texcoords[i[1]] + b2 * mesh.texcoords[i[2]];
      alpha *= sampleTexture(scene.textures[size_t(mat.baseColorTexture)], uv).a;
    }
  }
  if (!mesh.colors.empty()) alpha *= b0 * mesh.colors[i[0]].a + b1 * mesh.colors[i[1]].a + b2 * mesh.colors[i[2]].a;
  return alpha;
}

float opacityAt(const Scene& scene, const MeshInstance& mesh, uint32_t tri, float b1, float b2) {
  if (mesh.material < 0) return 1.0f;
  const Material& mat = scene.materials[size_t(mesh.material)];
  float coverage = 1.0f;
  if (mat.alphaMode == Material::AlphaMode::Mask)
    coverage = alphaAt(scene, mesh, tri, b1, b2) >= mat.alphaCutoff ? 1.0f : 0.0f;
  else if (mat.alphaMode == Material::AlphaMode::Blend)
    coverage = std::clamp(alphaAt(scene, mesh, tri, b1, b2), 0.0f, 1.0f);
  if (coverage == 0.0f || mat.transmissionFactor <= 0.0f) return coverage;
  float transmission = mat.transmissionFactor;
  if (mat.transmissionTexture >= 0 && !mesh.texcoords.empty()) {
    const uint32_t* i = &mesh.indices[3 * size_t(tri)];
    glm::vec2 uv = (1.0f - b1 - b2) * mesh.texcoords[i[0]] + b1 * mesh.texcoords[i[1]] + b2 * mesh.texcoords[i[2]];
    transmission *= scene.textures[size_t(mat.transmissionTexture)].sample(uv).r;
  }
  return coverage * (1.0f - std::clamp(transmission, 0.0f, 1.0f));
}

bool mayPassLight(const Scene& scene, const MeshInstance& mesh) {
  if (mesh.material < 0) return false;
  const Material& mat = scene.materials[size_t(mesh.material)];
  return mat.alphaMode != Material::AlphaMode::Opaque || mat.transmissionFactor > 0.0f;
}

std::vector<char> passesLight(const Scene& scene) {
  std::vector<float> textureMin(scene.textures.size(), -1.0f);  // -1: not scanned yet
  auto minAlpha = [&](int texture) {
    float& m = textureMin[size_t(texture)];
    if (m < 0.0f) {
      m = 1.0f;
      for (const glm::vec4& t : scene.textures[size_t(texture)].texels) m = std::min(m, std::max(t.a, 0.0f));
    }
    return m;
  };
  std::vector<char> out(scene.meshes.size(), 0);
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& mesh = scene.meshes[k];
    if (!mayPassLight(scene, mesh)) continue;
    const Material& mat = scene.materials[size_t(mesh.material)];
    if (mat.transmissionFactor > 0.0f) {
      out[k] = 1;
      continue;
    }
    float color = 1.0f;
    for (const glm::vec4& c : mesh.colors) color = std::min(color, std::max(c.a, 0.0f));
    const float texture = mat.baseColorTexture >= 0 && !mesh.texcoords.empty() ? minAlpha(mat.baseColorTexture) : 1.0f;
    const float alpha = std::max(mat.baseColorFactor.a, 0.0f) * texture * color;
    out[k] = mat.alphaMode == Material::AlphaMode::Mask ? alpha < mat.alphaCutoff : alpha < 1.0f;
  }
  return out;
}

}  // namespace prt
