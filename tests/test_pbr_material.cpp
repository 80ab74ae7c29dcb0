// The glTF metallic-roughness material in the scene model (prt/scene.h): every field read with
// the specification's defaults, bad values replaced with a warning naming the material, the
// baked file keeping them, the coordinate sets of textures that read other TEXCOORD_n or
// transforms, and the bake's diffuse albedo rule (docs/bake.md, "Materials").
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "gltf_file.h"
#include "harness.h"
#include "png_file.h"
#include "prt/brdf.h"
#include "prt/math.h"
#include "prt/relight.h"
#include "prt/scene.h"
#include "prt/sh.h"

namespace prt {
namespace {

using Json = nlohmann::json;

int vec2Accessor(test::GltfFile& f, const std::vector<float>& data) { return f.accessor(data, "VEC2"); }

/// A unit quad in the plane y = 0 facing +Y, TEXCOORD_0 = (x, z) and TEXCOORD_1 = (1 − x, z),
/// of material `material`, placed by a root node.
void addQuad(test::GltfFile& f, int material) {
  const std::vector<float> positions = {0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1};
  const std::vector<float> normals = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
  Json prim = {{"attributes",
                {{"POSITION", f.accessor(positions, "VEC3")},
                 {"NORMAL", f.accessor(normals, "VEC3")},
                 {"TEXCOORD_0", vec2Accessor(f, {0, 0, 1, 0, 1, 1, 0, 1})},
                 {"TEXCOORD_1", vec2Accessor(f, {1, 0, 0, 0, 0, 1, 1, 1})}}},
               {"indices", f.accessor<uint32_t>({0, 2, 1, 0, 3, 2}, "SCALAR", 5125)},
               {"material", material}};
  f.j["meshes"].push_back({{"primitives", Json::array({prim})}});
  f.node({{"mesh", f.j["meshes"].size() - 1}}, true);
}

/// Adds a 1×1 RGBA8 PNG as image and texture; returns the texture's index.
int addPixel(test::GltfFile& f, std::vector<uint8_t> rgba) {
  f.j["images"].push_back({{"uri", "data:image/png;base64," + test::base64(test::encodePng(1, 1, rgba))}});
  f.j["textures"].push_back({{"source", f.j["images"].size() - 1}});
  return int(f.j["textures"].size() - 1);
}

/// Every field set (material 0) and none (material 1), each on a quad.
test::GltfFile fullAndEmpty() {
  test::GltfFile f;
  const int mr = addPixel(f, {0, 51, 128, 255}), normal = addPixel(f, {128, 128, 255, 255});
  const int occlusion = addPixel(f, {100, 0, 0, 255}), emissive = addPixel(f, {188, 188, 188, 255});
  const int specular = addPixel(f, {0, 0, 0, 128}), specularColor = addPixel(f, {188, 255, 255, 255});
  const Json flip = {{"KHR_texture_transform", {{"offset", {0.5, 0}}, {"texCoord", 1}}}};
  f.j["materials"].push_back({{"name", "Full"},
                              {"pbrMetallicRoughness",
                               {{"metallicFactor", 0.25},
                                {"roughnessFactor", 0.6},
                                {"metallicRoughnessTexture", {{"index", mr}, {"extensions", flip}}}}},
                              {"normalTexture", {{"index", normal}, {"scale", 0.7}}},
                              {"occlusionTexture", {{"index", occlusion}, {"strength", 0.3}, {"texCoord", 1}}},
                              {"emissiveFactor", {0.5, 0.25, 1.0}},
                              {"emissiveTexture", {{"index", emissive}}},
                              {"extensions",
                               {{"KHR_materials_emissive_strength", {{"emissiveStrength", 5.0}}},
                                {"KHR_materials_ior", {{"ior", 1.33}}},
                                {"KHR_materials_specular",
                                 {{"specularFactor", 0.5},
                                  {"specularColorFactor", {1.0, 0.5, 0.25}},
                                  {"specularTexture", {{"index", specular}}},
                                  {"specularColorTexture", {{"index", specularColor}}}}}}}});
  f.j["materials"].push_back({{"name", "Empty"}});
  f.j["extensionsUsed"] = Json::array(
      {"KHR_texture_transform", "KHR_materials_emissive_strength", "KHR_materials_ior", "KHR_materials_specular"});
  addQuad(f, 0);
  addQuad(f, 1);
  return f;
}

void expectSameMaterial(const Material& a, const Material& b) {
  EXPECT_EQ(a.metallicFactor, b.metallicFactor);
  EXPECT_EQ(a.roughnessFactor, b.roughnessFactor);
  EXPECT_EQ(a.normalScale, b.normalScale);
  EXPECT_EQ(a.occlusionStrength, b.occlusionStrength);
  EXPECT_EQ(a.emissiveFactor, b.emissiveFactor);
  EXPECT_EQ(a.emissiveStrength, b.emissiveStrength);
  EXPECT_EQ(a.ior, b.ior);
  EXPECT_EQ(a.specularFactor, b.specularFactor);
  EXPECT_EQ(a.specularColorFactor, b.specularColorFactor);
  for (auto slot : {&Material::metallicRoughnessTexture, &Material::normalTexture, &Material::occlusionTexture,
                    &Material::emissiveTexture, &Material::specularTexture, &Material::specularColorTexture}) {
    EXPECT_EQ((a.*slot).texture >= 0, (b.*slot).texture >= 0);
    EXPECT_EQ((a.*slot).texCoord, (b.*slot).texCoord);
    EXPECT_EQ((a.*slot).uvSet, (b.*slot).uvSet);
  }
}

TEST(ScenePbrMaterial, EveryFieldIsReadWithTheSpecificationsDefaults) {
  test::TempDir dir;
  const std::string path = fullAndEmpty().write("pbr", dir.path());
  LoadOptions all;
  all.shadingTextures = true;
  const Scene s = loadScene(path, all);
  ASSERT_EQ(s.materials.size(), 2u);
  const Material& m = s.materials[0];
  EXPECT_FLOAT_EQ(m.metallicFactor, 0.25f);
  EXPECT_FLOAT_EQ(m.roughnessFactor, 0.6f);
  EXPECT_FLOAT_EQ(m.normalScale, 0.7f);
  EXPECT_FLOAT_EQ(m.occlusionStrength, 0.3f);
  EXPECT_EQ(m.emissiveFactor, glm::vec3(0.5f, 0.25f, 1.0f));
  EXPECT_FLOAT_EQ(m.emissiveStrength, 5.0f);
  EXPECT_FLOAT_EQ(m.ior, 1.33f);
  EXPECT_FLOAT_EQ(m.specularFactor, 0.5f);
  EXPECT_EQ(m.specularColorFactor, glm::vec3(1.0f, 0.5f, 0.25f));
  // Texels: linear for data (metallic-roughness B 128 → 128/255), sRGB-decoded for colours.
  ASSERT_GE(m.metallicRoughnessTexture.texture, 0);
  EXPECT_FLOAT_EQ(s.textures[size_t(m.metallicRoughnessTexture.texture)].texels[0].b, 128.0f / 255.0f);
  ASSERT_GE(m.emissiveTexture.texture, 0);
  EXPECT_NEAR(s.textures[size_t(m.emissiveTexture.texture)].texels[0].r, 0.5029f, 1e-3f);  // sRGB 188
  ASSERT_GE(m.specularTexture.texture, 0);
  EXPECT_FLOAT_EQ(s.textures[size_t(m.specularTexture.texture)].texels[0].a, 128.0f / 255.0f);
  for (auto slot : {&Material::normalTexture, &Material::occlusionTexture, &Material::specularColorTexture})
    EXPECT_GE((m.*slot).texture, 0);
  // Coordinate sets: the normal and emissive textures read the base colour's (TEXCOORD_0), the
  // occlusion TEXCOORD_1, the metallic-roughness TEXCOORD_1 shifted by 0.5 in u.
  EXPECT_EQ(m.normalTexture.uvSet, 0);
  EXPECT_EQ(m.emissiveTexture.uvSet, 0);
  EXPECT_EQ(m.occlusionTexture.texCoord, 1);
  EXPECT_EQ(m.metallicRoughnessTexture.texCoord, 1);
  EXPECT_NE(m.occlusionTexture.uvSet, m.metallicRoughnessTexture.uvSet);
  const MeshInstance& quad = s.meshes[0];
  ASSERT_EQ(quad.moreTexcoords.size(), 2u);
  EXPECT_EQ(quad.uvs(m.occlusionTexture.uvSet)[1], glm::vec2(0.0f, 0.0f));
  EXPECT_EQ(quad.uvs(m.metallicRoughnessTexture.uvSet)[1], glm::vec2(0.5f, 0.0f));
  EXPECT_EQ(quad.uvs(0)[1], glm::vec2(1.0f, 0.0f));
  EXPECT_EQ(quad.tangents.size(), quad.vertexCount());  // a normal texture and no TANGENT: generated
  // The material without any field: glTF's defaults, metallicFactor 1 among them.
  const Material& e = s.materials[1];
  EXPECT_EQ(e.metallicFactor, 1.0f);
  EXPECT_EQ(e.roughnessFactor, 1.0f);
  EXPECT_EQ(e.normalScale, 1.0f);
  EXPECT_EQ(e.occlusionStrength, 1.0f);
  EXPECT_EQ(e.emissiveFactor, glm::vec3(0.0f));
  EXPECT_EQ(e.emissiveStrength, 1.0f);
  EXPECT_EQ(e.ior, 1.5f);
  EXPECT_EQ(e.specularFactor, 1.0f);
  EXPECT_EQ(e.specularColorFactor, glm::vec3(1.0f));
  EXPECT_EQ(e.metallicRoughnessTexture.texture, -1);
  EXPECT_TRUE(s.meshes[1].tangents.empty());
  EXPECT_TRUE(s.warnings.empty()) << s.warnings[0];
  // Without shadingTextures only what the bake reads is decoded: the metallic-roughness texture.
  const Scene bake = loadScene(path);
  EXPECT_GE(bake.materials[0].metallicRoughnessTexture.texture, 0);
  for (auto slot : {&Material::normalTexture, &Material::occlusionTexture, &Material::emissiveTexture,
                    &Material::specularTexture, &Material::specularColorTexture})
    EXPECT_EQ((bake.materials[0].*slot).texture, -1);
  EXPECT_EQ(bake.textures.size(), 1u);
  EXPECT_EQ(bake.meshes[0].tangents, quad.tangents);  // tangents need no decoded texture
}

// The baked file is the input with attributes added: writeBakedScene carries the material
// through, extensions included, and a reload reads the same fields.
TEST(ScenePbrMaterial, BakedFileKeepsTheMaterial) {
  test::TempDir dir;
  LoadOptions all;
  all.shadingTextures = true;
  const Scene s = loadScene(fullAndEmpty().write("pbr", dir.path()), all);
  Scene withTransfer = s;
  withTransfer.transferBands = 1;
  for (MeshInstance& m : withTransfer.meshes) m.transfer.assign(m.vertexCount(), glm::vec3(1.0f));
  const std::string baked = dir.file("pbr.glb");
  writeBakedScene(s.path, withTransfer, nullptr, baked);
  const Scene back = loadScene(baked, all);
  ASSERT_EQ(back.materials.size(), 2u);
  for (size_t k = 0; k < 2; ++k) expectSameMaterial(back.materials[k], s.materials[k]);
  EXPECT_EQ(back.meshes[0].moreTexcoords, s.meshes[0].moreTexcoords);
  EXPECT_EQ(back.meshes[0].tangents, s.meshes[0].tangents);
  const test::Glb glb(baked);
  for (const char* ext : {"KHR_materials_emissive_strength", "KHR_materials_ior", "KHR_materials_specular"})
    EXPECT_NE(std::find(glb.j["extensionsUsed"].begin(), glb.j["extensionsUsed"].end(), ext),
              glb.j["extensionsUsed"].end())
        << ext;
}

// Out-of-range values: one warning each, naming the file, the material and the value used.
TEST(ScenePbrMaterial, BadValuesWarnNameTheMaterialAndWhatWasUsed) {
  test::TempDir dir;
  test::GltfFile f;
  f.j["materials"].push_back(
      {{"name", "Bad"},
       {"pbrMetallicRoughness", {{"metallicFactor", -0.5}, {"roughnessFactor", 2.0}}},
       {"occlusionTexture", {{"index", addPixel(f, {255, 0, 0, 255})}, {"strength", 1.5}}},
       {"emissiveFactor", {2.0, 0.5, -1.0}},
       {"extensions",
        {{"KHR_materials_emissive_strength", {{"emissiveStrength", -3.0}}},
         {"KHR_materials_ior", {{"ior", 0.5}}},
         {"KHR_materials_specular", {{"specularFactor", "strong"}, {"specularColorFactor", {-1.0, 1.0, 2.0}}}}}}});
  addQuad(f, 0);
  const Scene s = loadScene(f.write("bad", dir.path()));
  const Material& m = s.materials[0];
  EXPECT_EQ(m.metallicFactor, 0.0f);
  EXPECT_EQ(m.roughnessFactor, 1.0f);
  EXPECT_EQ(m.occlusionStrength, 1.0f);
  EXPECT_EQ(m.emissiveFactor, glm::vec3(1.0f, 0.5f, 0.0f));
  EXPECT_EQ(m.emissiveStrength, 0.0f);
  EXPECT_EQ(m.ior, 1.5f);
  EXPECT_EQ(m.specularFactor, 1.0f);
  EXPECT_EQ(m.specularColorFactor, glm::vec3(0.0f, 1.0f, 2.0f));  // above 1 is allowed
  const std::vector<std::string> expected = {"metallicFactor -0.5 is outside [0, 1]; 0 used",
                                             "roughnessFactor 2 is outside [0, 1]; 1 used",
                                             "occlusionTexture.strength 1.5 is outside",
                                             "emissiveFactor[0] 2 is outside [0, 1]; 1 used",
                                             "emissiveFactor[2] -1 is outside [0, 1]; 0 used",
                                             "emissiveStrength -3 is outside",
                                             "ior 0.5 is between 0 and 1",
                                             "specularFactor is not a number; 1 used",
                                             "specularColorFactor[0] -1 is outside"};
  ASSERT_EQ(s.warnings.size(), expected.size());
  for (size_t k = 0; k < expected.size(); ++k) {
    EXPECT_NE(s.warnings[k].find("material 0 'Bad'"), std::string::npos) << s.warnings[k];
    EXPECT_NE(s.warnings[k].find(expected[k]), std::string::npos) << s.warnings[k];
  }
}

// A normal texture reading coordinates the primitive lacks: a warning naming the material, no
// tangents, and the rest of the material as it is.
TEST(ScenePbrMaterial, NormalTextureWithoutItsCoordinatesIsIgnoredWithAWarning) {
  test::TempDir dir;
  test::GltfFile f;
  f.j["materials"].push_back(
      {{"name", "Bumpy"}, {"normalTexture", {{"index", addPixel(f, {128, 128, 255, 255})}, {"texCoord", 3}}}});
  addQuad(f, 0);
  const Scene s = loadScene(f.write("no_uv", dir.path()));
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("no TEXCOORD_3 for the textures of material 0 'Bumpy'"), std::string::npos)
      << s.warnings[0];
  EXPECT_TRUE(s.meshes[0].tangents.empty());
  EXPECT_TRUE(s.meshes[0].uvs(s.materials[0].normalTexture.uvSet).empty());
}

// A metallic-roughness texture that cannot be decoded: a warning naming the material, and the
// factor alone (metallic 0.5: half the base colour) instead of a refused file.
TEST(ScenePbrMaterial, UndecodableTextureLeavesTheFactorWithAWarning) {
  test::TempDir dir;
  test::GltfFile f;
  f.j["images"].push_back({{"uri", "data:image/png;base64," + test::base64(std::string("not an image"))}});
  f.j["textures"].push_back({{"source", 0}});
  f.j["materials"].push_back(
      {{"name", "Broken"},
       {"pbrMetallicRoughness", {{"metallicFactor", 0.5}, {"metallicRoughnessTexture", {{"index", 0}}}}}});
  addQuad(f, 0);
  const Scene s = loadScene(f.write("broken", dir.path()));
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("not a PNG or JPEG image (material 0 'Broken'); the texture is ignored"),
            std::string::npos)
      << s.warnings[0];
  EXPECT_EQ(s.materials[0].metallicRoughnessTexture.texture, -1);
  EXPECT_EQ(diffuseAlbedoAtVertex(s, s.meshes[0], 0), glm::vec3(0.5f));
}

// ---- The bake's diffuse albedo (docs/bake.md, "Materials")

/// The scene of one quad whose material is `material`, loaded.
Scene quadWith(const test::TempDir& dir, Json material, const std::vector<uint8_t>& mrTexel = {}) {
  test::GltfFile f;
  if (!mrTexel.empty())
    material["pbrMetallicRoughness"]["metallicRoughnessTexture"] = {{"index", addPixel(f, mrTexel)}};
  f.j["materials"].push_back(material);
  addQuad(f, 0);
  return loadScene(f.write("albedo", dir.path()));
}

// The diffuse albedo (diffuseAlbedoAtVertex, what `prt relight` takes) is baseColor ×
// (1 − metallic) × the dielectric's share; the bounce albedo (albedoAtVertex) adds the metal's
// lobe, metallic × (baseColor · Ā + B̄) at the material's roughness.
TEST(BakeAlbedo, IsTheDiffuseAlbedoPlusTheMetalsLobe) {
  test::TempDir dir;
  const Json base = {{"baseColorFactor", {0.8, 0.4, 0.2, 1.0}}};
  const glm::vec3 colour(0.8f, 0.4f, 0.2f);
  auto albedo = [&](Json material, const std::vector<uint8_t>& texel = {}) {
    const Scene s = quadWith(dir, std::move(material), texel);
    EXPECT_EQ(albedoAt(s, s.meshes[0], 0, 0.25f, 0.25f), albedoAtVertex(s, s.meshes[0], 0));  // uniform
    return diffuseAlbedoAtVertex(s, s.meshes[0], 0);
  };
  auto bounced = [&](Json material, const std::vector<uint8_t>& texel = {}) {
    const Scene s = quadWith(dir, std::move(material), texel);
    return albedoAtVertex(s, s.meshes[0], 0);
  };
  auto pbr = [&](double metallic) {
    Json p = base;
    p["metallicFactor"] = metallic;
    return Json{{"pbrMetallicRoughness", p}};
  };
  // A dielectric keeps the base colour, bit for bit: the bake's bytes of such scenes do not move.
  EXPECT_EQ(albedo(pbr(0.0)), colour);
  EXPECT_EQ(albedo(pbr(0.25)), colour * 0.75f);
  EXPECT_EQ(albedo(pbr(1.0)), glm::vec3(0.0f));
  EXPECT_EQ(albedo({{"pbrMetallicRoughness", base}}), glm::vec3(0.0f));  // metallicFactor absent: 1
  EXPECT_EQ(bounced(pbr(0.0)), colour);
  auto lobe = [&](double roughness) {
    const glm::dvec2 ab = brdf::cosineAveragedDfg(roughness);
    return glm::dvec3(colour) * ab.x + ab.y;
  };
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(bounced(pbr(0.25))[c], 0.75 * colour[c] + 0.25 * lobe(1.0)[c], 1e-6);
    Json copper = pbr(1.0);
    copper["pbrMetallicRoughness"]["roughnessFactor"] = 0.4;
    EXPECT_NEAR(bounced(copper)[c], lobe(0.4)[c], 1e-6);
    // Texture G scales roughness and B metallic: G = 102 (0.4) under factor 1, B = 51 (0.2).
    EXPECT_NEAR(bounced(pbr(1.0), {0, 102, 51, 255})[c], 0.8 * colour[c] + 0.2 * lobe(0.4)[c], 1e-5);
  }
  EXPECT_GT(lobe(0.4).x, 0.5);  // a metal sends back much of what it receives
  // prt relight writes ρ E/π with the diffuse albedo: a metal bounces its lobe but relights black,
  // a quarter-metal to 0.75 of the dielectric.
  auto relit = [&](Json material) {
    Scene s = quadWith(dir, std::move(material));
    s.transferBands = 1;
    for (MeshInstance& m : s.meshes) m.transfer.assign(m.vertexCount(), glm::vec3(1.0f));
    sh::ShRgb light(1);
    light.c[0] = glm::vec3(float(kPi));
    return relightVertices(s, light)[0][0];
  };
  EXPECT_EQ(relit(pbr(1.0)), glm::vec3(0.0f));
  EXPECT_NEAR(relit(pbr(0.25)).y, 0.75f * colour.y, 1e-6f);
  // The texture's B channel scales the factor: B = 51 (0.2) under factor 0.5 is metallic 0.1.
  EXPECT_NEAR(albedo(pbr(0.5), {0, 255, 51, 255}).x, 0.8f * (1.0f - 0.5f * 0.2f), 1e-6f);
  // Specular-glossiness and unlit materials, and no material: the base colour as before.
  EXPECT_EQ(
      albedo({{"extensions", {{"KHR_materials_pbrSpecularGlossiness", {{"diffuseFactor", {0.8, 0.4, 0.2, 1}}}}}}}),
      colour);
  Json unlit = {{"pbrMetallicRoughness", base}, {"extensions", {{"KHR_materials_unlit", Json::object()}}}};
  EXPECT_EQ(albedo(unlit), colour);
  // A weaker specular than the default (ior 1.33, or specularFactor 0) keeps the base colour; a
  // stronger one (ior 2, F0 = 0.111; specular colour ×2, F0 = 0.08) takes its extra share off.
  auto dielectric = [&](Json ext) {
    Json m = pbr(0.0);
    m["extensions"] = std::move(ext);
    return albedo(m);
  };
  const double w0 = brdf::dielectricDiffuseWeight(1.5, 1.0, glm::dvec3(1.0));
  EXPECT_EQ(dielectric({{"KHR_materials_ior", {{"ior", 1.33}}}}), colour);
  EXPECT_EQ(dielectric({{"KHR_materials_specular", {{"specularFactor", 0.0}}}}), colour);
  const double ior2 = brdf::dielectricDiffuseWeight(2.0, 1.0, glm::dvec3(1.0)) / w0;
  EXPECT_NEAR(dielectric({{"KHR_materials_ior", {{"ior", 2.0}}}}).x, 0.8 * ior2, 1e-6);
  EXPECT_NEAR(ior2, (1.0 - (1.0 / 9 + 8.0 / 9 * brdf::kHalfVectorFresnelMean)) / w0, 1e-9);
  EXPECT_LT(ior2, 0.94);
  const double doubled = brdf::dielectricDiffuseWeight(1.5, 1.0, glm::dvec3(2.0, 1.0, 1.0)) / w0;
  EXPECT_NEAR(dielectric({{"KHR_materials_specular", {{"specularColorFactor", {2.0, 1.0, 1.0}}}}}).y, 0.4 * doubled,
              1e-6);
  EXPECT_LT(doubled, 0.97);
}

}  // namespace
}  // namespace prt
