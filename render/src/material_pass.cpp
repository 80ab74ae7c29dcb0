// The glTF metallic-roughness material on the GPU (MaterialShading::Full; docs/render.md,
// "Materials"): per instance its factors, its slots' textures and coordinate sets, its tangents;
// per frame the camera, the DFG table and the environment's maps prefiltered by roughness
// (environment_prefilter.h), bound for the MATERIAL programs (material_inputs.glsl,
// material_shading.glsl).
#include <algorithm>
#include <cmath>
#include <set>

#include "environment_prefilter.h"
#include "prt/brdf.h"
#include "prt/error.h"
#include "renderer_impl.h"
#include "shader_sources.h"

namespace prt::render {

namespace {

/// The DFG table's samples per entry (Hammersley points; its size: kDfgSize).
constexpr int kDfgSamples = 512;

GlBuffer vertexBuffer(const GlFunctions& gl, const void* data, size_t bytes) {
  GlBuffer buffer = createBuffer(gl);
  gl.NamedBufferStorage(buffer, GLsizeiptr(std::max<size_t>(bytes, 1)), bytes ? data : nullptr, 0);
  return buffer;
}

void enableAttribute(const GlFunctions& gl, GLuint vao, GLuint location, GLuint buffer, GLint components) {
  gl.VertexArrayVertexBuffer(vao, location, buffer, 0, GLsizei(components * sizeof(float)));
  gl.VertexArrayAttribFormat(vao, location, components, GL_FLOAT, GL_FALSE, 0);
  gl.VertexArrayAttribBinding(vao, location, location);
  gl.EnableVertexArrayAttrib(vao, location);
}

// The dielectric's diffuse share against the default dielectric's (prt::diffuseScale's rule:
// exactly 1 for ior 1.5 without KHR_materials_specular).
float dielectricScale(const Material& m) {
  if (m.ior == 1.5f && m.specularFactor == 1.0f && m.specularColorFactor == glm::vec3(1.0f)) return 1.0f;
  static const double kDefault = brdf::dielectricDiffuseWeight(1.5, 1.0, glm::dvec3(1.0));
  const double w = brdf::dielectricDiffuseWeight(m.ior, m.specularFactor, glm::dvec3(m.specularColorFactor));
  return float(std::min(1.0, w / kDefault));
}

}  // namespace

void Renderer::Impl::setFullMaterial(const Scene& scene, const MeshInstance& m, Instance& in, bool receiver) {
  FullMaterial& f = in.full;
  if (m.material < 0) return;  // no material: white and Lambertian, as the bake takes it
  const Material& mat = scene.materials.at(size_t(m.material));
  if (mat.unlit || mat.specularGlossiness) return;  // Lambertian with the base colour, as the bake
  auto warn = [&](const std::string& what) {
    const std::string line = cat("material '", mat.name, "': ", what);
    if (std::find(warnings.begin(), warnings.end(), line) == warnings.end()) warnings.push_back(line);
  };
  f.factors = glm::vec4(mat.metallicFactor, mat.roughnessFactor, mat.normalScale, mat.occlusionStrength);
  f.emissive = mat.emissiveFactor * mat.emissiveStrength;
  brdf::MetallicRoughness mr;
  mr.ior = mat.ior;
  mr.specular = mat.specularFactor;
  mr.specularColor = glm::dvec3(mat.specularColorFactor);
  f.specularColor = glm::vec4(glm::vec3(mr.dielectricF0Color()), mat.specularFactor);
  f.diffuseScale = dielectricScale(mat);
  const TextureSlot* slots[4] = {&mat.metallicRoughnessTexture, &mat.normalTexture, &mat.occlusionTexture,
                                 &mat.emissiveTexture};
  const char* names[4] = {"metallicRoughnessTexture", "normalTexture", "occlusionTexture", "emissiveTexture"};
  int second = -1;  // the one coordinate set beyond TEXCOORD's first that the shaders read
  for (int i = 0; i < 4; ++i) {
    const TextureSlot& slot = *slots[i];
    // A texture the loader could not decode is -1 already (it warned); so is a set the
    // primitive lacks (empty uvs, warned too): the factor alone.
    if (slot.texture < 0 || m.uvs(slot.uvSet).empty()) continue;
    const Texture& t = scene.textures.at(size_t(slot.texture));
    if (t.width < 1 || t.height < 1 || t.texels.size() != size_t(t.width) * size_t(t.height)) {
      warn(cat(names[i], " '", t.name, "' holds no texels: its factor alone is used"));
      continue;
    }
    if (slot.uvSet >= 1 && second >= 0 && slot.uvSet != second) {
      warn(cat(names[i], " reads TEXCOORD_", slot.texCoord, " besides another second set: its factor alone is used"));
      continue;
    }
    if (i == 1 && m.tangents.size() != m.vertexCount()) {
      warn(cat("normalTexture without tangents on instance '", m.name, "': the vertex normal is used"));
      continue;
    }
    if (slot.uvSet >= 1) second = slot.uvSet;
    f.slots[i] = slot.uvSet >= 1 ? 1 : 0;
    f.textures[size_t(i)] = sceneTexture(scene, slot.texture);
  }
  if (f.slots != glm::ivec4(-1)) f.variantBits |= kVariantMaterialTextures;
  if (f.slots.x < 0 && mat.roughnessFactor >= kRoughSpecularRoughness) f.variantBits |= kVariantRoughSpecular;
  if (f.slots[1] >= 0) {
    f.tangents = vertexBuffer(gl, m.tangents.data(), m.tangents.size() * sizeof(glm::vec4));
    f.vertexInputs |= 1;
    if (receiver) enableAttribute(gl, in.vao, 4, f.tangents, 4);
  }
  if (second >= 1) {
    const std::vector<glm::vec2>& uv = m.uvs(second);
    f.texcoords1 = vertexBuffer(gl, uv.data(), uv.size() * sizeof(glm::vec2));
    f.vertexInputs |= 2;
    if (receiver) enableAttribute(gl, in.vao, 5, f.texcoords1, 2);
  }
  checkError(cat("uploading the material of '", m.name, "'").c_str());
}

void Renderer::Impl::setFullMaterialUniforms(const Program& p, const Instance& in) {
  const FullMaterial& f = in.full;
  gl.ProgramUniform4fv(p.id, p.material, 1, &f.factors.x);
  gl.ProgramUniform3fv(p.id, p.emissive, 1, &f.emissive.x);
  gl.ProgramUniform4fv(p.id, p.specularColor, 1, &f.specularColor.x);
  gl.ProgramUniform1f(p.id, p.diffuseScale, f.diffuseScale);
  gl.ProgramUniform4iv(p.id, p.slots, 1, &f.slots.x);
  gl.ProgramUniform1i(p.id, p.vertexInputs, f.vertexInputs | (in.transferDirect ? 4 : 0));
  for (int i = 0; i < 4; ++i)
    if (f.textures[size_t(i)]) gl.BindTextureUnit(kMaterialFirstUnit + GLuint(i), f.textures[size_t(i)]);
}

void Renderer::Impl::bindMaterialBuffers(const Instance& in, bool direct) {
  if (in.full.tangents) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, in.full.tangents);
  if (in.full.texcoords1) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 7, in.full.texcoords1);
  if (!direct && in.transferDirect) {
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, in.transferDirect);
    if (in.transferDirectBack) gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, in.transferDirectBack);
  }
}

// The environment's maps prefiltered by roughness (once per image) in one 3D texture: map i's
// level k is slice i · levels + k, so that one trilinear lookup blends two levels. Slices, not
// mip levels: llvmpipe samples a mipmapped texture at a per-pixel lod several times slower than
// lookups at lod 0; and one texture, not one sampler per map, so that the shader's loop over the
// maps indexes no samplers (docs/render.md, "Cost of the materials"). Made again only when the
// frame's maps change.
void Renderer::Impl::bindReflections(const RigBackground* env) {
  std::vector<const ImageRgb*> key;
  if (env)
    for (const RigBackground::Map& m : env->maps) key.push_back(m.image.get());
  if (key.empty() || (reflectionArray && key == reflectionKey)) return;
  std::vector<const std::vector<ImageRgb>*> all;
  for (const RigBackground::Map& m : env->maps) {
    auto it = reflections.find(m.image.get());
    if (it == reflections.end())
      it = reflections.emplace(m.image.get(), std::make_pair(m.image, prefilterEnvironment(*m.image))).first;
    all.push_back(&it->second.second);
  }
  const int w = kPrefilterWidth, h = kPrefilterWidth;  // octahedral levels
  GlTexture tex = createTexture(gl, GL_TEXTURE_3D);
  gl.TextureStorage3D(tex, 1, GL_RGB32F, w, h, GLsizei(all.size() * kPrefilterLevels));
  gl.PixelStorei(GL_UNPACK_ALIGNMENT, 4);
  for (size_t i = 0; i < all.size(); ++i)
    for (size_t k = 0; k < size_t(kPrefilterLevels); ++k)
      gl.TextureSubImage3D(tex, 0, 0, 0, GLint(i * kPrefilterLevels + k), w, h, 1, GL_RGB, GL_FLOAT,
                           (*all[i])[k].pixels.data());
  gl.TextureParameteri(tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  gl.TextureParameteri(tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  gl.TextureParameteri(tex, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  gl.TextureParameteri(tex, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  gl.TextureParameteri(tex, GL_TEXTURE_WRAP_R, GL_CLAMP_TO_EDGE);
  checkError("uploading the prefiltered environment maps");
  reflectionArray = std::move(tex);
  reflectionKey = std::move(key);
}

void Renderer::Impl::beginMaterialFrame(const Frame& frame, const FramePlan& plan) {
  const bool baked = plan.bakedExtra & kVariantFullMaterial;
  const bool recv = plan.drawReceivers && (plan.receiverExtra & kVariantFullMaterial);
  if (!baked && !recv) return;
  if (!dfg) {
    // Entries on a grid that includes its ends, n·v and roughness = i / (size − 1), so that a
    // lookup at roughness 1 or n·v 1 reads the table there, not clamped half an entry short
    // (material_shading.glsl maps x to (x (size − 1) + ½) / size). Roughness below the
    // shaders' floor and n·v = 0 take the nearest value they reach.
    std::vector<glm::vec2> ab(size_t(kDfgSize) * kDfgSize);
    for (int row = 0; row < kDfgSize; ++row)
      for (int col = 0; col < kDfgSize; ++col) {
        const double roughness = std::max(double(row) / (kDfgSize - 1), 0.045);
        const double nDotV = std::max(double(col) / (kDfgSize - 1), 1e-3);
        ab[size_t(row) * kDfgSize + size_t(col)] = glm::vec2(brdf::integrateDfg(nDotV, roughness, kDfgSamples));
      }
    dfg = linearFloatTexture(GL_RG32F, GL_RG, kDfgSize, kDfgSize, ab.data(), GL_CLAMP_TO_EDGE, GL_CLAMP_TO_EDGE);
  }
  const GLuint dfgUnit = kEnvironmentFirstUnit + 1;
  gl.BindTextureUnit(dfgUnit, dfg);
  const RigBackground* env = frame.environment;
  const int maps = envMaps;  // planFrame: the frame's, checked
  std::vector<glm::mat3> toMap;
  std::vector<glm::vec3> scale;
  bindReflections(env);
  if (maps) gl.BindTextureUnit(kEnvironmentFirstUnit, reflectionArray);
  for (int i = 0; i < maps; ++i) {
    toMap.emplace_back(env->maps[size_t(i)].worldToMap);
    scale.emplace_back(env->maps[size_t(i)].scale);
  }
  const glm::vec3 uniform(env ? env->uniform : glm::dvec3(0.0));
  const glm::dmat4& c = frame.camera.cameraToWorld;
  const glm::vec4 eye =
      frame.camera.perspective ? glm::vec4(glm::vec3(c[3]), 1.0f) : glm::vec4(glm::normalize(-glm::vec3(c[2])), 0.0f);
  std::set<GLuint> done;
  auto set = [&](const Program& p) {
    if (!done.insert(p.id).second) return;
    gl.ProgramUniform4fv(p.id, p.eye, 1, &eye.x);
    gl.ProgramUniform1i(p.id, p.envOn, env ? 1 : 0);
    if (maps) {
      gl.ProgramUniformMatrix3fv(p.id, p.envWorldToMap, maps, GL_FALSE, &toMap[0][0][0]);
      gl.ProgramUniform3fv(p.id, p.envScale, maps, &scale[0].x);
    }
    gl.ProgramUniform3fv(p.id, p.envUniform, 1, &uniform.x);
    gl.ProgramUniform1f(p.id, p.envMaxLod, float(kPrefilterLevels - 1));
  };
  if (baked)
    for (const Instance& in : instances) set(bakedProgram(variantOf(in, plan.bakedExtra)));
  if (recv)
    for (const Instance& in : receivers) set(receiverProgram(frame.probeLookup, variantOf(in, plan.receiverExtra)));
  checkError("setting the material uniforms");
}

}  // namespace prt::render
