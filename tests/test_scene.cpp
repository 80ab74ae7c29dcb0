// glTF scene loading and the baked / lit .glb writers. Every test writes its own small glTF
// (JSON built here, buffers as data: URIs or a .bin beside it) into a fresh temporary folder.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "harness.h"
#include "png_file.h"
#include "prt/bake/surface_bake.h"
#include "prt/bake_record.h"
#include "prt/error.h"
#include "prt/scene.h"
#include "test_util.h"

namespace {

using prt::test::base64;
using prt::test::encodePng;
using prt::test::encodePngRaw;
using prt::test::pngChunk;

namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr int kFloat = 5126;
constexpr int kUnsignedByte = 5121;
constexpr int kUnsignedInt = 5125;
// Positions and normals go through float and a double matrix: a few ulps.
constexpr float kTol = 1e-5f;

/// Builds a glTF document with one binary buffer.
class GltfBuilder {
 public:
  Json doc = {{"asset", {{"version", "2.0"}}}};
  std::string bin;

  int view(const void* data, size_t size) {
    bin.resize((bin.size() + 3) / 4 * 4, '\0');
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", size}});
    bin.append(static_cast<const char*>(data), size);
    return int(doc["bufferViews"].size()) - 1;
  }
  int accessor(const void* data, size_t size, int componentType, size_t count, const char* type,
               bool normalized = false) {
    Json a = {{"bufferView", view(data, size)}, {"componentType", componentType}, {"count", count}, {"type", type}};
    if (normalized) a["normalized"] = true;
    doc["accessors"].push_back(a);
    return int(doc["accessors"].size()) - 1;
  }
  int floats(const std::vector<float>& v, const char* type, int components) {
    return accessor(v.data(), v.size() * 4, kFloat, v.size() / size_t(components), type);
  }
  int vec3(const std::vector<float>& v) { return floats(v, "VEC3", 3); }
  int indices(const std::vector<uint32_t>& v) {
    return accessor(v.data(), v.size() * 4, kUnsignedInt, v.size(), "SCALAR");
  }
  int add(const char* array, const Json& value) {
    doc[array].push_back(value);
    return int(doc[array].size()) - 1;
  }
  int mesh(const Json& primitives) { return add("meshes", {{"primitives", primitives}}); }
  int node(const Json& node) { return add("nodes", node); }
  void scene(const std::vector<int>& roots) {
    doc["scenes"] = Json::array({{{"nodes", roots}}});
    doc["scene"] = 0;
  }
  /// Writes the .gltf; the buffer goes beside it as a .bin file or inline as a data: URI.
  std::string write(const fs::path& path, bool binBeside = false) {
    Json d = doc;
    if (!bin.empty()) {
      Json buffer = {{"byteLength", bin.size()}};
      if (binBeside) {
        std::string name = path.stem().string() + ".bin";
        std::ofstream(path.parent_path() / name, std::ios::binary) << bin;
        buffer["uri"] = name;
      } else {
        buffer["uri"] = "data:application/octet-stream;base64," + base64(bin);
      }
      d["buffers"] = Json::array({buffer});
    }
    std::ofstream(path) << d.dump(1);
    return path.string();
  }
  /// Writes a .glb: the JSON chunk, then the buffer as the BIN chunk.
  std::string writeGlb(const fs::path& path) {
    Json d = doc;
    std::string data = bin;
    data.resize((data.size() + 3) / 4 * 4, '\0');
    d["buffers"] = Json::array({{{"byteLength", bin.size()}}});
    std::string json = d.dump();
    json.resize((json.size() + 3) / 4 * 4, ' ');
    auto little = [](std::string& s, uint32_t v) { s.append(reinterpret_cast<const char*>(&v), 4); };
    std::string out = "glTF";
    little(out, 2);
    little(out, uint32_t(12 + 8 + json.size() + 8 + data.size()));
    little(out, uint32_t(json.size()));
    out += "JSON" + json;
    little(out, uint32_t(data.size()));
    out += std::string("BIN\0", 4) + data;
    std::ofstream(path, std::ios::binary) << out;
    return path.string();
  }
};

const std::vector<float> kTriangle = {0, 0, 0, 1, 0, 0, 0, 1, 0};

Json trianglePrimitive(GltfBuilder& b, const std::vector<float>& positions = kTriangle) {
  return {{"attributes", {{"POSITION", b.vec3(positions)}}}};
}

std::string readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

uint32_t readLittle32(const std::string& s, size_t at) {
  uint32_t v;
  std::memcpy(&v, s.data() + at, 4);
  return v;
}

/// The JSON chunk of a .glb file.
Json glbJson(const fs::path& path) {
  std::string s = readBytes(path);
  EXPECT_EQ(s.substr(0, 4), "glTF");
  return Json::parse(s.substr(20, readLittle32(s, 12)));
}

/// The BIN chunk of a .glb file.
std::string glbBin(const fs::path& path) {
  std::string s = readBytes(path);
  size_t at = 20 + readLittle32(s, 12);
  if (at + 8 > s.size()) return "";
  return s.substr(at + 8, readLittle32(s, at));
}

void expectNear(const glm::vec3& a, const glm::vec3& b, float tol = kTol) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

double srgbToLinearRef(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

class SceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::path(::testing::TempDir()) / (std::string("prt_scene_") + info->test_suite_name() + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// Loading `path` must throw prt::Error naming the file and containing every `part`.
  void expectError(const std::string& path, const std::vector<std::string>& parts,
                   const prt::LoadOptions& options = {}) {
    try {
      prt::loadScene(path, options);
      ADD_FAILURE() << "no error for " << path;
    } catch (const prt::Error& e) {
      std::string what = e.what();
      EXPECT_NE(what.find(fs::path(path).filename().string()), std::string::npos) << what;
      for (const std::string& part : parts) EXPECT_NE(what.find(part), std::string::npos) << what;
    }
  }

  fs::path dir_;
};

// ---------------------------------------------------------------------------------------------

using SceneLoad = SceneTest;

TEST_F(SceneLoad, NestedTrsAndMatrixGiveWorldPositions) {
  GltfBuilder b;
  int mesh = b.mesh(Json::array({trianglePrimitive(b)}));
  // Child: a matrix translating by +1 in x (column-major, translation in the last column).
  int child = b.node({{"mesh", mesh}, {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1, 0, 0, 1}}});
  const double s = std::sqrt(0.5);
  // Parent: T(1,2,3) · R(90° about +Z) · S(2).
  int parent =
      b.node({{"children", {child}}, {"translation", {1, 2, 3}}, {"rotation", {0, 0, s, s}}, {"scale", {2, 2, 2}}});
  b.scene({parent});
  prt::Scene scene = prt::loadScene(b.write(dir_ / "nested.gltf", /*binBeside=*/true));
  ASSERT_EQ(scene.meshes.size(), 1u);
  const prt::MeshInstance& m = scene.meshes[0];
  EXPECT_EQ(m.node, child);
  EXPECT_EQ(m.mesh, mesh);
  // p -> child (+1,0,0) -> scale 2 -> rotate (x,y) -> (-y,x) -> translate (1,2,3).
  expectNear(m.positions[0], {1, 4, 3});
  expectNear(m.positions[1], {1, 6, 3});
  expectNear(m.positions[2], {-1, 4, 3});
  expectNear(scene.boundsMin, {-1, 4, 3});
  expectNear(scene.boundsMax, {1, 6, 3});
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2}));
  // Computed normal of a CCW triangle in the XY plane stays +Z under this transform.
  expectNear(m.normals[0], {0, 0, 1});
}

TEST_F(SceneLoad, NormalsUseInverseTransposeUnderNonUniformScale) {
  GltfBuilder b;
  const float r = std::sqrt(0.5f);
  Json prim = trianglePrimitive(b);
  prim["attributes"]["NORMAL"] = b.vec3({r, r, 0, r, r, 0, r, r, 0});
  int mesh = b.mesh(Json::array({prim}));
  b.scene({b.node({{"mesh", mesh}, {"scale", {2, 1, 1}}})});
  prt::Scene scene = prt::loadScene(b.write(dir_ / "scaled.gltf"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  // M^-T = diag(1/2, 1, 1): (1,1,0) -> (0.5, 1, 0), normalised.
  glm::vec3 expected = glm::normalize(glm::vec3(0.5f, 1.0f, 0.0f));
  for (const glm::vec3& n : scene.meshes[0].normals) expectNear(n, expected);
  expectNear(scene.meshes[0].positions[1], {2, 0, 0});
}

TEST_F(SceneLoad, ZeroNormalsAreRepairedAreaWeighted) {
  GltfBuilder b;
  // Triangle A (area 2, normal +Z) and triangle B (area 0.5, normal +Y) share vertex 0, whose
  // given normal is zero.
  Json prim = trianglePrimitive(b, {0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 1, 1, 0, 0});
  prim["attributes"]["NORMAL"] = b.vec3({0, 0, 0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1, 0});
  prim["indices"] = b.indices({0, 1, 2, 0, 3, 4});
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  prt::Scene scene = prt::loadScene(b.write(dir_ / "normals.gltf"));
  const prt::MeshInstance& m = scene.meshes[0];
  EXPECT_EQ(m.vertexCount(), 5u);
  expectNear(m.normals[0], glm::normalize(glm::vec3(0, 1, 4)));  // weights 2·area: 4 and 1
  expectNear(m.normals[1], {0, 0, 1});
  expectNear(m.normals[3], {0, 1, 0});
  ASSERT_EQ(scene.warnings.size(), 1u);
  EXPECT_NE(scene.warnings[0].find("1 zero or non-finite normals replaced"), std::string::npos) << scene.warnings[0];
}

TEST_F(SceneLoad, WithoutNormalsTheSameMeshIsSplitForFlatNormals) {
  GltfBuilder b;
  // The same two triangles without NORMAL: glTF asks for flat normals, so vertex 0, shared by
  // faces of two orientations, becomes two vertices.
  Json prim = trianglePrimitive(b, {0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 1, 1, 0, 0});
  prim["indices"] = b.indices({0, 1, 2, 0, 3, 4});
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  prt::Scene scene = prt::loadScene(b.write(dir_ / "flat.gltf"));
  const prt::MeshInstance& m = scene.meshes[0];
  ASSERT_EQ(m.vertexCount(), 6u);
  EXPECT_EQ(m.fileVertex, (std::vector<uint32_t>{0, 1, 2, 3, 4, 0}));
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2, 5, 3, 4}));
  for (uint32_t v : {0, 1, 2}) expectNear(m.normals[v], {0, 0, 1});
  for (uint32_t v : {3, 4, 5}) expectNear(m.normals[v], {0, 1, 0});
  expectNear(m.positions[5], m.positions[0]);
  EXPECT_TRUE(scene.warnings.empty());
}

TEST_F(SceneLoad, StripsAndFansBecomeTriangleLists) {
  GltfBuilder b;
  Json strip = trianglePrimitive(b, {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0});
  strip["mode"] = 5;  // non-indexed
  Json fan = trianglePrimitive(b, {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, -1, 1, 0});
  fan["mode"] = 6;
  fan["indices"] = b.indices({0, 1, 2, 3, 4});
  b.scene({b.node({{"mesh", b.mesh(Json::array({strip, fan}))}})});
  prt::Scene scene = prt::loadScene(b.write(dir_ / "strips.gltf"));
  ASSERT_EQ(scene.meshes.size(), 2u);
  // Strip: triangle i is (i, i+1, i+2) for even i, (i, i+2, i+1) for odd i.
  EXPECT_EQ(scene.meshes[0].indices, (std::vector<uint32_t>{0, 1, 2, 1, 3, 2}));
  // Fan: (i+1, i+2, 0).
  EXPECT_EQ(scene.meshes[1].indices, (std::vector<uint32_t>{1, 2, 0, 2, 3, 0, 3, 4, 0}));
  EXPECT_EQ(scene.meshes[1].vertexCount(), 5u);
  for (const prt::MeshInstance& m : scene.meshes)
    for (const glm::vec3& n : m.normals) expectNear(n, {0, 0, 1});  // all front-facing
}

TEST_F(SceneLoad, NonIndexedTrianglesGetSequentialIndices) {
  GltfBuilder b;
  Json prim = trianglePrimitive(b, {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 0, 1, 1});
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  prt::Scene scene = prt::loadScene(b.write(dir_ / "flat.gltf"));
  EXPECT_EQ(scene.meshes[0].indices, (std::vector<uint32_t>{0, 1, 2, 3, 4, 5}));
  EXPECT_EQ(scene.meshes[0].triangleCount(), 2u);
}

TEST_F(SceneLoad, MirroringNodeFlipsWindingToStayFrontFacing) {
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  prim["attributes"]["NORMAL"] = b.vec3({0, 0, 1, 0, 0, 1, 0, 0, 1});
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}, {"scale", {-1, 1, 1}}})});
  prt::Scene scene = prt::loadScene(b.write(dir_ / "mirror.gltf"));
  const prt::MeshInstance& m = scene.meshes[0];
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 2, 1}));
  glm::vec3 face = glm::cross(m.positions[m.indices[1]] - m.positions[m.indices[0]],
                              m.positions[m.indices[2]] - m.positions[m.indices[0]]);
  expectNear(glm::normalize(face), {0, 0, 1});
  expectNear(m.normals[0], {0, 0, 1});  // the given normal agrees with the flipped winding
}

/// A textured triangle: 2×2 PNG (red, green / blue, grey 188), baseColorFactor (0.5, 1, 1, 1),
/// COLOR_0 as normalized bytes. `imageUri` empty: the PNG goes inline as a data: URI.
std::string writeTexturedScene(const fs::path& dir, const std::string& imageUri, std::string* png) {
  *png = encodePng(2, 2, {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 188, 188, 188, 255});
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  prim["attributes"]["TEXCOORD_0"] = b.floats({0.25f, 0.25f, 0.75f, 0.25f, 0.25f, 0.75f}, "VEC2", 2);
  std::vector<uint8_t> colors = {255, 255, 255, 255, 255, 51, 255, 255, 255, 255, 255, 255};
  prim["attributes"]["COLOR_0"] = b.accessor(colors.data(), colors.size(), kUnsignedByte, 3, "VEC4", true);
  prim["material"] = 0;
  b.doc["materials"] = Json::array(
      {{{"pbrMetallicRoughness",
         {{"metallicFactor", 0}, {"baseColorFactor", {0.5, 1, 1, 1}}, {"baseColorTexture", {{"index", 0}}}}}}});
  b.doc["textures"] = Json::array({{{"source", 0}, {"sampler", 0}}});
  b.doc["samplers"] = Json::array({{{"wrapS", 33071}, {"wrapT", 33648}}});
  if (imageUri.empty()) {
    b.doc["images"] = Json::array({{{"uri", "data:image/png;base64," + base64(*png)}}});
  } else {
    std::ofstream(dir / imageUri, std::ios::binary) << *png;
    b.doc["images"] = Json::array({{{"uri", imageUri}}});
  }
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  return b.write(dir / "textured.gltf");
}

TEST_F(SceneLoad, MaterialAlbedoCombinesFactorSrgbTextureAndColor) {
  std::string png;
  prt::Scene scene = prt::loadScene(writeTexturedScene(dir_, "albedo.png", &png));
  ASSERT_EQ(scene.textures.size(), 1u);
  const prt::Texture& tex = scene.textures[0];
  EXPECT_EQ(tex.width, 2);
  EXPECT_EQ(tex.height, 2);
  EXPECT_EQ(tex.wrapS, 33071);
  EXPECT_EQ(tex.wrapT, 33648);
  const float grey = float(srgbToLinearRef(188.0 / 255.0));
  EXPECT_NEAR(tex.texels[3].r, grey, 1e-6f);
  EXPECT_NEAR(tex.texels[3].a, 1.0f, 1e-6f);
  const prt::MeshInstance& m = scene.meshes[0];
  ASSERT_EQ(scene.materials.size(), 1u);
  EXPECT_EQ(m.material, 0);
  ASSERT_EQ(m.colors.size(), 3u);
  EXPECT_NEAR(m.colors[1].g, 0.2f, 1e-6f);  // 51/255
  // Texel centres: vertex 0 samples red, 1 green, 2 blue.
  expectNear(prt::albedoAtVertex(scene, m, 0), {0.5f, 0, 0});
  expectNear(prt::albedoAtVertex(scene, m, 1), {0, 0.2f, 0});
  expectNear(prt::albedoAtVertex(scene, m, 2), {0, 0, 1});
  expectNear(prt::albedoAt(scene, m, 0, 0.0f, 0.0f), {0.5f, 0, 0});
  // Halfway between vertices 1 and 2: uv (0.5, 0.5) is the mean of the four texels, colour
  // interpolated to (1, 0.6, 1).
  glm::vec3 mean = (glm::vec3(1, 0, 0) + glm::vec3(0, 1, 0) + glm::vec3(0, 0, 1) + glm::vec3(grey)) / 4.0f;
  expectNear(prt::albedoAt(scene, m, 0, 0.5f, 0.5f), mean * glm::vec3(0.5f, 0.6f, 1.0f));
}

// An 8-bit image keeps its bytes (Texture::texels8), which sample() reads: the same texels,
// exactly (each byte's decode is the float texel), so every lookup gives the float path's bits,
// across the wrap modes and at texel centres, edges and beyond the texture.
TEST_F(SceneLoad, EightBitTexelsSampleTheBitsOfTheFloatOnes) {
  std::string png;
  prt::Scene scene = prt::loadScene(writeTexturedScene(dir_, "albedo8.png", &png));
  ASSERT_EQ(scene.textures.size(), 1u);
  const prt::Texture& eight = scene.textures[0];
  ASSERT_EQ(eight.texels8.size(), eight.texels.size());
  for (size_t i = 0; i < eight.texels.size(); ++i)
    for (int c = 0; c < 4; ++c)
      EXPECT_EQ(eight.texels[i][c], eight.levels8[c < 3 ? 0 : 1][(eight.texels8[i] >> (8 * c)) & 255u])
          << i << " " << c;
  prt::Texture floats = eight;
  floats.texels8.clear();
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-2.5f, 2.5f);
  int differ = 0;
  for (int mode : {prt::Texture::kRepeat, prt::Texture::kClampToEdge, prt::Texture::kMirroredRepeat}) {
    prt::Texture a = eight, b = floats;
    a.wrapS = a.wrapT = b.wrapS = b.wrapT = mode;
    for (int k = 0; k < 20000; ++k) {
      const glm::vec2 uv =
          k < 16 ? glm::vec2(0.25f * float(k % 4) + 0.125f, 0.25f * float(k / 4)) : glm::vec2(u(rng), u(rng));
      differ += a.sample(uv) != b.sample(uv);
    }
  }
  EXPECT_EQ(differ, 0);
}

/// A .glb whose base colour image lives in a buffer view (2×1: red, green).
GltfBuilder texturedGlb() {
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  prim["attributes"]["TEXCOORD_0"] = b.floats({0.25f, 0.5f, 0.75f, 0.5f, 0.75f, 0.5f}, "VEC2", 2);
  prim["material"] = 0;
  std::string png = encodePng(2, 1, {255, 0, 0, 255, 0, 255, 0, 255});
  b.doc["images"] = Json::array({{{"bufferView", b.view(png.data(), png.size())}, {"mimeType", "image/png"}}});
  b.doc["textures"] = Json::array({{{"source", 0}}});
  b.doc["materials"] =
      Json::array({{{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorTexture", {{"index", 0}}}}}}});
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  return b;
}

TEST_F(SceneLoad, GlbWithImageInBufferView) {
  prt::Scene scene = prt::loadScene(texturedGlb().writeGlb(dir_ / "embedded.glb"));
  ASSERT_EQ(scene.meshes.size(), 1u);
  expectNear(prt::albedoAtVertex(scene, scene.meshes[0], 0), {1, 0, 0});
  expectNear(prt::albedoAtVertex(scene, scene.meshes[0], 1), {0, 1, 0});
}

TEST_F(SceneLoad, DefaultMaterialIsWhite) {
  GltfBuilder b;
  b.scene({b.node({{"mesh", b.mesh(Json::array({trianglePrimitive(b)}))}})});
  prt::Scene scene = prt::loadScene(b.write(dir_ / "white.gltf"));
  EXPECT_EQ(scene.meshes[0].material, -1);
  expectNear(prt::albedoAtVertex(scene, scene.meshes[0], 1), {1, 1, 1});
}

TEST_F(SceneLoad, CameraAndSpotLightInWorldSpace) {
  GltfBuilder b;
  int mesh = b.mesh(Json::array({trianglePrimitive(b)}));
  b.doc["cameras"] = Json::array({{{"type", "perspective"},
                                   {"name", "cam"},
                                   {"perspective", {{"yfov", 0.5}, {"znear", 0.1}, {"aspectRatio", 1.5}}}}});
  b.doc["extensionsUsed"] = {"KHR_lights_punctual"};
  b.doc["extensions"]["KHR_lights_punctual"]["lights"] =
      Json::array({{{"type", "spot"},
                    {"name", "lamp"},
                    {"color", {1, 0.5, 0.25}},
                    {"intensity", 10},
                    {"spot", {{"innerConeAngle", 0.2}, {"outerConeAngle", 0.6}}}}});
  const double s = std::sqrt(0.5);
  int cam = b.node({{"camera", 0}, {"translation", {0, 0, 5}}});
  int light = b.node({{"translation", {0, 3, 0}},
                      {"rotation", {-s, 0, 0, s}},  // -90° about X
                      {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  b.scene({b.node({{"mesh", mesh}}), b.node({{"children", {cam, light}}, {"translation", {1, 0, 0}}})});
  prt::Scene scene = prt::loadScene(b.write(dir_ / "camlight.gltf"));
  ASSERT_EQ(scene.cameras.size(), 1u);
  const prt::Camera& c = scene.cameras[0];
  EXPECT_EQ(c.name, "cam");
  EXPECT_EQ(c.node, cam);
  EXPECT_TRUE(c.perspective);
  EXPECT_DOUBLE_EQ(c.yfov, 0.5);
  EXPECT_DOUBLE_EQ(c.znear, 0.1);
  EXPECT_DOUBLE_EQ(c.aspectRatio, 1.5);
  expectNear(glm::vec3(c.world[3]), {1, 0, 5});
  ASSERT_EQ(scene.lights.size(), 1u);
  const prt::PunctualLight& l = scene.lights[0];
  EXPECT_EQ(l.type, prt::PunctualLight::Type::Spot);
  EXPECT_EQ(l.name, "lamp");
  expectNear(l.color, {1, 0.5f, 0.25f});
  EXPECT_FLOAT_EQ(l.intensity, 10.0f);
  expectNear(l.position, {1, 3, 0});
  expectNear(l.direction, {0, -1, 0});  // local -Z turned -90° about X points down
  EXPECT_FLOAT_EQ(l.innerConeAngle, 0.2f);
  EXPECT_FLOAT_EQ(l.outerConeAngle, 0.6f);
}

TEST_F(SceneLoad, ReceiversByNameIndexAndExtrasCoverSubtrees) {
  GltfBuilder b;
  int mesh = b.mesh(Json::array({trianglePrimitive(b)}));
  int ball = b.node({{"name", "Ball"}, {"mesh", mesh}});
  int group = b.node({{"name", "Group"}, {"children", {ball}}});
  int floor = b.node({{"name", "Floor"}, {"mesh", mesh}});
  int toy = b.node({{"name", "Toy"}, {"mesh", mesh}});
  int prop = b.node({{"name", "Prop"}, {"children", {toy}}, {"extras", {{"prt", {{"receiver", true}}}}}});
  b.scene({group, floor, prop});
  std::string path = b.write(dir_ / "receivers.gltf");
  auto receiverOf = [](const prt::Scene& s, int node) {
    for (const prt::MeshInstance& m : s.meshes)
      if (m.node == node) return m.receiverOnly;
    ADD_FAILURE() << "no instance for node " << node;
    return false;
  };
  prt::Scene plain = prt::loadScene(path);
  EXPECT_FALSE(receiverOf(plain, ball));
  EXPECT_FALSE(receiverOf(plain, floor));
  EXPECT_TRUE(receiverOf(plain, toy));  // by extras, inherited from Prop

  prt::LoadOptions options;
  options.receiverNodes = {"Group", std::to_string(floor)};
  prt::Scene marked = prt::loadScene(path, options);
  EXPECT_TRUE(receiverOf(marked, ball));   // by name, inherited from Group
  EXPECT_TRUE(receiverOf(marked, floor));  // by index
  EXPECT_TRUE(receiverOf(marked, toy));
  EXPECT_EQ(prt::describeReceivers(marked),
            (std::vector<std::string>{"node 0 'Ball': named in LoadOptions::receiverNodes",
                                      "node 2 'Floor': named in LoadOptions::receiverNodes",
                                      "node 3 'Toy': extras.prt.receiver"}));

  // The baked file marks the --receiver nodes in their extras: loaded again without options
  // (as prt render loads it), the same instances are receivers. Other extras are kept.
  b.doc["nodes"][size_t(floor)]["extras"] = {{"note", "kept"}, {"prt", {{"other", 1}}}};
  path = b.write(dir_ / "receivers_extras.gltf");
  prt::Scene named = prt::loadScene(path, options);
  const std::string baked = (dir_ / "receivers.glb").string();
  prt::writeBakedScene(path, named, nullptr, baked);
  prt::Scene reread = prt::loadScene(baked);
  for (const prt::MeshInstance& m : reread.meshes) {
    EXPECT_TRUE(m.receiverOnly) << m.name;
    EXPECT_EQ(m.receiverReason, prt::ReceiverReason::Extras) << m.name;
  }
  std::ifstream in(baked, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  uint32_t jsonLength = 0;  // GLB: 12-byte header, then the JSON chunk's length, type and bytes
  ASSERT_GT(bytes.size(), 20u);
  std::memcpy(&jsonLength, bytes.data() + 12, 4);
  const Json written = Json::parse(bytes.substr(20, jsonLength));
  EXPECT_EQ(written["nodes"][size_t(floor)]["extras"],
            Json({{"note", "kept"}, {"prt", {{"other", 1}, {"receiver", true}}}}));
}

TEST_F(SceneLoad, LinesAreSkippedWithAWarning) {
  GltfBuilder b;
  Json lines = trianglePrimitive(b);
  lines["mode"] = 1;
  b.scene({b.node({{"mesh", b.mesh(Json::array({lines, trianglePrimitive(b)}))}})});
  std::string path = b.write(dir_ / "lines.gltf");
  prt::Scene scene = prt::loadScene(path);
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_EQ(scene.meshes[0].primitive, 1);
  ASSERT_EQ(scene.warnings.size(), 1u);
  EXPECT_EQ(scene.warnings[0], path + ": mesh 0 / primitive 0: skipping mode LINES (only triangles are baked)");
}

// ---------------------------------------------------------------------------------------------

using SceneTextureSample = SceneTest;

TEST_F(SceneTextureSample, BilinearWithWrapModes) {
  prt::Texture t;
  t.width = 2;
  t.height = 1;
  t.texels = {glm::vec4(0.0f), glm::vec4(1.0f)};
  auto at = [&](float u, int wrap) {
    t.wrapS = t.wrapT = wrap;
    return t.sample({u, 0.5f}).r;
  };
  const int repeat = 10497, clamp = 33071, mirror = 33648;
  EXPECT_FLOAT_EQ(at(0.25f, repeat), 0.0f);  // texel centres are exact
  EXPECT_FLOAT_EQ(at(0.75f, repeat), 1.0f);
  EXPECT_FLOAT_EQ(at(0.5f, repeat), 0.5f);  // halfway between the centres
  EXPECT_FLOAT_EQ(at(0.0f, repeat), 0.5f);  // edge: blends with the texel across the seam
  EXPECT_FLOAT_EQ(at(0.0f, clamp), 0.0f);
  EXPECT_FLOAT_EQ(at(0.0f, mirror), 0.0f);   // mirrored: the neighbour is itself
  EXPECT_FLOAT_EQ(at(1.25f, repeat), 0.0f);  // one period on: texel 0 again
  EXPECT_FLOAT_EQ(at(1.25f, mirror), 1.0f);  // mirrored period: texel 1
  EXPECT_FLOAT_EQ(at(1.25f, clamp), 1.0f);
}

// ---------------------------------------------------------------------------------------------

using SceneErrors = SceneTest;

TEST_F(SceneErrors, MissingFile) { expectError((dir_ / "absent.gltf").string(), {"no such file"}); }

TEST_F(SceneErrors, MalformedJson) {
  std::ofstream(dir_ / "broken.gltf") << "{ \"asset\": { \"version\": ";
  expectError((dir_ / "broken.gltf").string(), {"malformed glTF"});
}

TEST_F(SceneErrors, IndexOutOfRange) {
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  prim["indices"] = b.indices({0, 1, 5});
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  expectError(b.write(dir_ / "badindex.gltf"), {"mesh 0 / primitive 0 / indices", "index 2 is 5"});
}

TEST_F(SceneErrors, AccessorPastBufferEnd) {
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  b.doc["accessors"][0]["count"] = 4;  // 48 bytes from a 36-byte view
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  expectError(b.write(dir_ / "short.gltf"), {"mesh 0 / primitive 0 / POSITION", "runs past the end"});
}

TEST_F(SceneErrors, BufferViewPastBufferEnd) {
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  b.doc["bufferViews"][0]["byteOffset"] = 1000;
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  expectError(b.write(dir_ / "view.gltf"), {"POSITION", "buffer view 0"});
}

TEST_F(SceneErrors, ImageBufferViewPastBufferEnd) {
  GltfBuilder b = texturedGlb();
  b.doc["bufferViews"][b.doc["images"][0]["bufferView"].get<int>()]["byteLength"] = 100000;
  expectError(b.writeGlb(dir_ / "image.glb"), {"malformed glTF", "image 0", "outside its buffer"});
}

TEST_F(SceneErrors, EmptyDataUriImage) {
  GltfBuilder b;
  b.doc["images"] = Json::array({{{"uri", "data:image/png;base64,"}}});
  b.scene({b.node({{"mesh", b.mesh(Json::array({trianglePrimitive(b)}))}})});
  expectError(b.write(dir_ / "emptyimage.gltf"), {"malformed glTF"});
}

TEST_F(SceneErrors, NonFinitePosition) {
  GltfBuilder b;
  Json prim = trianglePrimitive(b, {0, 0, 0, std::numeric_limits<float>::quiet_NaN(), 0, 0, 0, 1, 0});
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  expectError(b.write(dir_ / "nan.gltf"), {"mesh 0 / primitive 0 / POSITION: vertex 1 is not finite"});
}

TEST_F(SceneLoad, DegenerateTrianglesDroppedWithOneWarningPerPrimitive) {
  GltfBuilder b;
  Json prim = trianglePrimitive(b, {0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 0, 0});
  prim["attributes"]["NORMAL"] = b.vec3({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1});
  // Triangle 1 is collinear, triangle 2 repeats an index.
  prim["indices"] = b.indices({0, 1, 2, 0, 1, 3, 2, 2, 1});
  const int mesh = b.mesh(Json::array({prim}));
  b.scene({b.node({{"mesh", mesh}}), b.node({{"mesh", mesh}, {"translation", {0, 0, 1}}})});
  prt::Scene scene = prt::loadScene(b.write(dir_ / "degenerate.gltf"));
  ASSERT_EQ(scene.meshes.size(), 2u);
  for (const prt::MeshInstance& m : scene.meshes) {
    EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2}));
    EXPECT_EQ(m.vertexCount(), 4u);  // vertices stay one to one
  }
  // One warning for the primitive, though two nodes place it.
  ASSERT_EQ(scene.warnings.size(), 1u);
  EXPECT_NE(scene.warnings[0].find("mesh 0 / primitive 0: dropped 2 degenerate (zero-area) triangles (the first is "
                                   "triangle 1) of 3"),
            std::string::npos)
      << scene.warnings[0];
}

TEST_F(SceneErrors, UnknownRequiredExtension) {
  GltfBuilder b;
  b.doc["extensionsUsed"] = {"EXT_made_up"};
  b.doc["extensionsRequired"] = {"EXT_made_up"};
  b.scene({b.node({{"mesh", b.mesh(Json::array({trianglePrimitive(b)}))}})});
  expectError(b.write(dir_ / "ext.gltf"), {"required extension EXT_made_up"});
}

TEST_F(SceneErrors, NodeCycle) {
  GltfBuilder b;
  int mesh = b.mesh(Json::array({trianglePrimitive(b)}));
  b.node({{"children", {1}}});
  b.node({{"children", {2}}, {"mesh", mesh}});
  b.node({{"children", {1}}});
  b.scene({0});
  expectError(b.write(dir_ / "cycle.gltf"), {"node 1", "cycle"});
}

TEST_F(SceneErrors, NoTriangles) {
  GltfBuilder b;
  Json points = trianglePrimitive(b);
  points["mode"] = 0;
  b.scene({b.node({{"mesh", b.mesh(Json::array({points}))}})});
  expectError(b.write(dir_ / "points.gltf"), {"no triangle geometry in the default scene"});
}

TEST_F(SceneErrors, UnknownReceiverName) {
  GltfBuilder b;
  b.scene({b.node({{"name", "Floor"}, {"mesh", b.mesh(Json::array({trianglePrimitive(b)}))}})});
  prt::LoadOptions options;
  options.receiverNodes = {"Nope"};
  expectError(b.write(dir_ / "receiver.gltf"), {"no node named 'Nope'"}, options);
}

// ---------------------------------------------------------------------------------------------

using SceneWrite = SceneTest;

/// Two nodes share mesh 0 (a triangle); node 2 holds a strip.
std::string writeInstancedScene(const fs::path& dir) {
  GltfBuilder b;
  int tri = b.mesh(Json::array({trianglePrimitive(b)}));
  Json strip = trianglePrimitive(b, {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0});
  strip["mode"] = 5;
  int stripMesh = b.mesh(Json::array({strip}));
  b.scene({b.node({{"name", "A"}, {"mesh", tri}}), b.node({{"name", "B"}, {"mesh", tri}, {"translation", {5, 0, 0}}}),
           b.node({{"name", "S"}, {"mesh", stripMesh}, {"translation", {0, 5, 0}}})});
  return b.write(dir / "instanced.gltf");
}

/// A record of a made-up bake of instanced.gltf.
prt::BakeRecord bakeRecordOf(int bands, int samples) {
  prt::BakeRecord r;
  r.scene = "instanced.gltf";
  r.bands = bands;
  r.samples = samples;
  r.bounces = 1;
  r.seed = 11;
  r.prtVersion = "9.8.7";
  return r;
}

/// Distinct made-up transfer for every instance, vertex and coefficient.
void fillTransfer(prt::Scene& scene, int bands) {
  scene.transferBands = bands;
  size_t k = size_t(bands) * bands;
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    prt::MeshInstance& inst = scene.meshes[m];
    inst.transfer.resize(inst.vertexCount() * k);
    for (size_t v = 0; v < inst.vertexCount(); ++v)
      for (size_t i = 0; i < k; ++i)
        inst.transfer[v * k + i] = glm::vec3(float(100 * m + 10 * v + i), -float(m + 1), 0.5f * float(i));
  }
}

TEST_F(SceneWrite, BakedRoundTripKeepsTransferPerInstance) {
  std::string input = writeInstancedScene(dir_);
  prt::Scene scene = prt::loadScene(input);
  ASSERT_EQ(scene.meshes.size(), 3u);
  fillTransfer(scene, 2);
  const prt::BakeRecord record = bakeRecordOf(2, 256);
  fs::path out = dir_ / "baked.glb";
  prt::writeBakedScene(input, scene, &record, out.string());

  prt::Scene baked = prt::loadScene(out.string());
  EXPECT_EQ(baked.transferBands, 2);
  ASSERT_TRUE(baked.bakeRecord.has_value());
  EXPECT_EQ(*baked.bakeRecord, record);
  ASSERT_EQ(baked.meshes.size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(baked.meshes[k].node, scene.meshes[k].node);
    EXPECT_EQ(baked.meshes[k].transfer.size(), baked.meshes[k].vertexCount() * 4);  // 2 bands
    EXPECT_EQ(baked.meshes[k].transfer, scene.meshes[k].transfer) << "instance " << k;
    EXPECT_EQ(baked.meshes[k].indices, scene.meshes[k].indices);
    for (size_t v = 0; v < scene.meshes[k].vertexCount(); ++v)
      expectNear(baked.meshes[k].positions[v], scene.meshes[k].positions[v]);
  }
  // Nodes A and B no longer share a mesh.
  EXPECT_EQ(baked.meshes[0].mesh, 0);
  EXPECT_NE(baked.meshes[1].mesh, baked.meshes[0].mesh);

  Json doc = glbJson(out);
  EXPECT_EQ(doc["asset"]["generator"], "prt");
  EXPECT_EQ(doc["meshes"].size(), 3u);
  ASSERT_EQ(doc["buffers"].size(), 1u);
  EXPECT_FALSE(doc["buffers"][0].contains("uri"));
  for (const Json& mesh : doc["meshes"]) {
    const Json& prim = mesh["primitives"][0];
    EXPECT_EQ(prim.value("mode", 4), 4);  // the strip became a list
    // glTF requires POSITION bounds; the input had none, the writer adds them.
    const Json& position = doc["accessors"][prim["attributes"]["POSITION"].get<int>()];
    EXPECT_EQ(position["min"].size(), 3u);
    EXPECT_EQ(position["max"].size(), 3u);
    for (const char* name : {"_PRT_SH_00", "_PRT_SH_01", "_PRT_SH_02", "_PRT_SH_03"}) {
      ASSERT_TRUE(prim["attributes"].contains(name)) << name;
      const Json& a = doc["accessors"][prim["attributes"][name].get<int>()];
      EXPECT_EQ(a["type"], "VEC3");
      EXPECT_EQ(a["componentType"], kFloat);
    }
  }
}

TEST_F(SceneWrite, RebakingReplacesTransfer) {
  std::string input = writeInstancedScene(dir_);
  prt::Scene scene = prt::loadScene(input);
  fillTransfer(scene, 3);
  fs::path first = dir_ / "first.glb", second = dir_ / "second.glb";
  const prt::BakeRecord firstRecord = bakeRecordOf(3, 64), secondRecord = bakeRecordOf(2, 128);
  prt::writeBakedScene(input, scene, &firstRecord, first.string());
  prt::Scene again = prt::loadScene(first.string());
  fillTransfer(again, 2);
  prt::writeBakedScene(first.string(), again, &secondRecord, second.string());
  prt::Scene result = prt::loadScene(second.string());
  EXPECT_EQ(result.transferBands, 2);
  EXPECT_EQ(result.meshes[1].transfer, again.meshes[1].transfer);
  EXPECT_EQ(result.bakeRecord, secondRecord);
  EXPECT_LT(fs::file_size(second), fs::file_size(first));  // old coefficients are not carried along
}

TEST_F(SceneWrite, TexturedSceneKeepsItsImageAndAlbedo) {
  for (const std::string uri : {"tex.png", ""}) {
    SCOPED_TRACE(uri.empty() ? "data URI image" : "image file");
    std::string png;
    std::string input = writeTexturedScene(dir_, uri, &png);
    prt::Scene scene = prt::loadScene(input);
    fillTransfer(scene, 1);
    fs::path out = dir_ / "textured.glb";
    prt::writeBakedScene(input, scene, nullptr, out.string());
    prt::Scene baked = prt::loadScene(out.string());
    EXPECT_FALSE(baked.bakeRecord.has_value());
    for (uint32_t v = 0; v < 3; ++v)
      expectNear(prt::albedoAtVertex(baked, baked.meshes[0], v), prt::albedoAtVertex(scene, scene.meshes[0], v));
    // The image travels as its original PNG bytes in a buffer view.
    Json doc = glbJson(out);
    const Json& image = doc["images"][0];
    EXPECT_FALSE(image.contains("uri"));
    EXPECT_EQ(image["mimeType"], "image/png");
    const Json& view = doc["bufferViews"][image["bufferView"].get<int>()];
    std::string bin = glbBin(out);
    EXPECT_EQ(bin.substr(view.value("byteOffset", 0), view["byteLength"].get<size_t>()), png);
    // Writing again from the .glb keeps the image that is now in a buffer view.
    fs::path again = dir_ / "again.glb";
    prt::writeBakedScene(out.string(), baked, nullptr, again.string());
    prt::Scene twice = prt::loadScene(again.string());
    for (uint32_t v = 0; v < 3; ++v)
      expectNear(prt::albedoAtVertex(twice, twice.meshes[0], v), prt::albedoAtVertex(scene, scene.meshes[0], v));
  }
}

TEST_F(SceneWrite, LitSceneHasRadianceColorsUnlitMaterialsAndNoTransfer) {
  std::string input = writeInstancedScene(dir_);
  prt::Scene scene = prt::loadScene(input);
  fillTransfer(scene, 3);
  fs::path baked = dir_ / "baked.glb", lit = dir_ / "lit.glb";
  const prt::BakeRecord record = bakeRecordOf(3, 64);
  prt::writeBakedScene(input, scene, &record, baked.string());
  prt::Scene bakedScene = prt::loadScene(baked.string());
  std::vector<std::vector<glm::vec3>> radiance(bakedScene.meshes.size());
  for (size_t k = 0; k < radiance.size(); ++k)
    for (size_t v = 0; v < bakedScene.meshes[k].vertexCount(); ++v)
      radiance[k].push_back(glm::vec3(float(k), float(v), 2.5f));  // above 1 on purpose
  radiance[1].clear();                                             // node B is left out
  prt::writeLitScene(baked.string(), bakedScene, radiance, lit.string());

  prt::Scene shown = prt::loadScene(lit.string());
  EXPECT_EQ(shown.transferBands, 0);
  ASSERT_EQ(shown.meshes.size(), 2u);
  EXPECT_EQ(shown.meshes[0].node, bakedScene.meshes[0].node);
  EXPECT_EQ(shown.meshes[1].node, bakedScene.meshes[2].node);
  // COLOR_0, what a viewer shows, is the radiance clamped to 0..1 (_RADIANCE, the exact values:
  // test_scene_write_valid.cpp).
  for (size_t k : {0u, 1u}) {
    const prt::MeshInstance& m = shown.meshes[k];
    const auto& expected = radiance[k == 0 ? 0 : 2];
    ASSERT_EQ(m.colors.size(), expected.size());
    for (size_t v = 0; v < expected.size(); ++v) {
      expectNear(glm::vec3(m.colors[v]), glm::clamp(expected[v], 0.0f, 1.0f));
      EXPECT_EQ(m.colors[v].a, 1.0f);
    }
    ASSERT_GE(m.material, 0);
    EXPECT_TRUE(shown.materials[size_t(m.material)].unlit);
    expectNear(prt::albedoAtVertex(shown, m, 0), glm::clamp(expected[0], 0.0f, 1.0f));
  }
  Json doc = glbJson(lit);
  EXPECT_NE(std::find(doc["extensionsUsed"].begin(), doc["extensionsUsed"].end(), "KHR_materials_unlit"),
            doc["extensionsUsed"].end());
  for (const Json& mat : doc["materials"]) {
    EXPECT_TRUE(mat["extensions"].contains("KHR_materials_unlit"));
    EXPECT_FALSE(mat.value("pbrMetallicRoughness", Json::object()).contains("baseColorTexture"));
  }
  EXPECT_FALSE(doc["nodes"][bakedScene.meshes[1].node].contains("mesh"));
  EXPECT_EQ(doc["meshes"].size(), 2u);  // B's own copy of the mesh is gone, not left empty
  for (const Json& mesh : doc["meshes"])
    for (const Json& prim : mesh["primitives"]) {
      EXPECT_EQ(doc["accessors"][prim["attributes"]["COLOR_0"].get<int>()]["type"], "VEC3");
      EXPECT_EQ(doc["accessors"][prim["attributes"]["_RADIANCE"].get<int>()]["type"], "VEC3");
      for (const auto& [name, index] : prim["attributes"].items())
        EXPECT_EQ(name.rfind("_PRT_SH_", 0), std::string::npos);
    }
  // 9 transfer coefficients per vertex are gone from the binary chunk, not just unreferenced.
  EXPECT_LT(glbBin(lit).size(), glbBin(baked).size() / 3);
}

TEST_F(SceneWrite, MissingDirectoryThrowsAndLeavesNoFile) {
  std::string input = writeInstancedScene(dir_);
  prt::Scene scene = prt::loadScene(input);
  fs::path out = dir_ / "no" / "such" / "dir" / "baked.glb";
  EXPECT_THROW(prt::writeBakedScene(input, scene, nullptr, out.string()), prt::Error);
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(dir_ / "no"));
  std::vector<std::vector<glm::vec3>> radiance(scene.meshes.size());
  EXPECT_THROW(prt::writeLitScene(input, scene, radiance, out.string()), prt::Error);
  EXPECT_FALSE(fs::exists(out));
}

// The writer checks a record as the reader would: prt never writes a file it refuses to load.
TEST_F(SceneWrite, InvalidBakeRecordIsRefusedWithoutOutput) {
  std::string input = writeInstancedScene(dir_);
  prt::Scene scene = prt::loadScene(input);
  fillTransfer(scene, 2);
  fs::path out = dir_ / "baked.glb";
  prt::BakeRecord noBands = bakeRecordOf(0, 64), otherBands = bakeRecordOf(3, 64);
  for (const auto& [record, message] :
       {std::pair{&noBands, "asset.extras.prt.bands: expected an integer 1..8, got 0"},
        std::pair{&otherBands, "asset.extras.prt.bands: 3, but the transfer holds 2 bands"}}) {
    try {
      prt::writeBakedScene(input, scene, record, out.string());
      ADD_FAILURE() << "no error for " << message;
    } catch (const prt::Error& e) {
      EXPECT_NE(std::string(e.what()).find(prt::cat(out.string(), ": ", message)), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(out));
  }
}

// ---------------------------------------------------------------------------------------------

using SceneBakeRecord = SceneTest;

/// asset.extras.prt exactly as prt bake wrote it before prt_version was recorded.
Json olderRecord() {
  return Json::parse(R"({"version": 1, "scene": "room.gltf", "bands": 3, "samples": 1024, "bounces": 2,
      "shadowed": true, "seed": 1, "transfer": "irradiance",
      "sh_convention": "real orthonormal, no Condon-Shortley phase, index l(l+1)+m, glTF axes",
      "units": "E = transfer . light (irradiance); L_o = albedo / pi * E"})");
}

/// A one-triangle .glb whose asset.extras.prt is `record` (null: none); the node is a receiver
/// when asked.
std::string writeRecordScene(const fs::path& path, const Json& record, bool receiver = false) {
  GltfBuilder b;
  Json node = {{"mesh", b.mesh(Json::array({trianglePrimitive(b)}))}};
  if (receiver) node["extras"] = {{"prt", {{"receiver", true}}}};
  b.scene({b.node(node)});
  if (!record.is_null()) b.doc["asset"]["extras"] = {{"prt", record}, {"other_tool", 5}};
  return b.writeGlb(path);
}

TEST_F(SceneBakeRecord, BakedFileGivesBackTheSameRecord) {
  const std::string input = writeInstancedScene(dir_);
  prt::bake::BakeSettings big;
  big.bands = 2;
  big.samples = 8;
  big.bounces = 1;
  big.seed = 3000000000u;  // above tinygltf's 32-bit integers: stored as a double, exactly
  prt::bake::BakeSettings unshadowed = big;
  unshadowed.shadowed = false;  // recorded with 0 bounces
  unshadowed.seed = 5;
  for (const prt::bake::BakeSettings& settings : {big, unshadowed}) {
    prt::Scene scene = prt::loadScene(input);
    const prt::bake::SurfaceTransfer t = prt::bake::bakeSurface(scene, settings);
    for (size_t k = 0; k < scene.meshes.size(); ++k) scene.meshes[k].transfer = t.perMesh[k];
    scene.transferBands = t.bands;
    const prt::BakeRecord record = prt::bake::bakeRecord(settings, "instanced.gltf", "0.1.0");
    EXPECT_EQ(record.bounces, settings.shadowed ? 1 : 0);
    const fs::path out = dir_ / "baked.glb";
    prt::writeBakedScene(input, scene, &record, out.string());
    const prt::Scene baked = prt::loadScene(out.string());
    ASSERT_TRUE(baked.bakeRecord.has_value());
    EXPECT_EQ(*baked.bakeRecord, record);
    EXPECT_EQ(baked.bakeRecord->seed, settings.seed);
    EXPECT_EQ(baked.bakeRecord->prtVersion, "0.1.0");
    // The fixed descriptions travel with the fields, for readers without prt.
    const Json stored = glbJson(out)["asset"]["extras"]["prt"];
    EXPECT_EQ(stored["transfer"], prt::BakeRecord::kTransfer);
    EXPECT_EQ(stored["sh_convention"], prt::BakeRecord::kShConvention);
    EXPECT_EQ(stored["units"], prt::BakeRecord::kUnits);
    EXPECT_EQ(stored["version"], prt::BakeRecord::kLayoutVersion);
  }
}

TEST_F(SceneBakeRecord, OlderRecordWithoutPrtVersionReads) {
  Json record = olderRecord();
  record["sky"] = "studio.exr";  // keys this prt does not know are ignored
  const prt::Scene scene = prt::loadScene(writeRecordScene(dir_ / "older.glb", record));
  ASSERT_TRUE(scene.bakeRecord.has_value());
  const prt::BakeRecord& r = *scene.bakeRecord;
  EXPECT_EQ(r.scene, "room.gltf");
  EXPECT_EQ(r.bands, 3);
  EXPECT_EQ(r.samples, 1024);
  EXPECT_EQ(r.bounces, 2);
  EXPECT_TRUE(r.shadowed);
  EXPECT_EQ(r.seed, 1u);
  EXPECT_EQ(r.prtVersion, "");
  EXPECT_EQ(prt::describeBakeRecord(r), "3 bands, 1024 samples, 2 bounces, shadowed, seed 1, from room.gltf");
  record["prt_version"] = "0.1.0";
  record["bounces"] = 1;
  record["shadowed"] = false;
  EXPECT_EQ(prt::describeBakeRecord(*prt::loadScene(writeRecordScene(dir_ / "newer.glb", record)).bakeRecord),
            "3 bands, 1024 samples, 1 bounce, unshadowed, seed 1, from room.gltf, prt 0.1.0");
}

TEST_F(SceneBakeRecord, FileWithoutRecordLoads) {
  const prt::Scene scene = prt::loadScene(writeRecordScene(dir_ / "plain.glb", nullptr));
  EXPECT_FALSE(scene.bakeRecord.has_value());
  EXPECT_EQ(scene.transferBands, 0);
}

TEST_F(SceneBakeRecord, MalformedRecordIsRefusedNamingFileAndField) {
  struct Case {
    const char* key;
    Json value;  // null: the key is removed
    std::string message;
  };
  const std::vector<Case> cases = {
      {"bands", "x", R"(asset.extras.prt.bands: expected an integer 1..8, got "x")"},
      {"bands", 99, "asset.extras.prt.bands: expected an integer 1..8, got 99"},
      {"bands", 0, "asset.extras.prt.bands: expected an integer 1..8, got 0"},
      {"bands", 2.5, "asset.extras.prt.bands: expected an integer 1..8, got 2.5"},
      {"bands", nullptr, "asset.extras.prt.bands: missing"},
      {"samples", 0, "asset.extras.prt.samples: expected an integer >= 1, got 0"},
      {"bounces", -1, "asset.extras.prt.bounces: expected an integer >= 0, got -1"},
      {"seed", -1, "asset.extras.prt.seed: expected an unsigned integer, got -1"},
      {"seed", 1.5, "asset.extras.prt.seed: expected an unsigned integer, got 1.5"},
      {"seed", "7", R"(asset.extras.prt.seed: expected an unsigned integer, got "7")"},
      {"shadowed", "yes", R"(asset.extras.prt.shadowed: expected true or false, got "yes")"},
      {"scene", 3, "asset.extras.prt.scene: expected a string, got 3"},
      {"transfer", "radiance", R"(asset.extras.prt.transfer: expected "irradiance", got "radiance")"},
      {"units", nullptr, "asset.extras.prt.units: missing"},
      {"prt_version", 1, "asset.extras.prt.prt_version: expected a string, got 1"},
      {"version", 2, "asset.extras.prt.version: 2: written by a newer prt (this one reads version 1)"},
      {"version", 0, "asset.extras.prt.version: expected 1, got 0"},
      {"version", "1", R"(asset.extras.prt.version: expected an integer, got "1")"},
  };
  for (size_t k = 0; k < cases.size(); ++k) {
    SCOPED_TRACE(cases[k].message);
    Json record = olderRecord();
    if (cases[k].value.is_null())
      record.erase(cases[k].key);
    else
      record[cases[k].key] = cases[k].value;
    // A newer layout is named before anything else in it is judged.
    if (cases[k].message.find("newer") != std::string::npos) record["bands"] = "whatever";
    expectError(writeRecordScene(dir_ / prt::cat("bad", k, ".glb"), record), {cases[k].message});
  }
  expectError(writeRecordScene(dir_ / "string.glb", "x"), {R"(asset.extras.prt: expected an object, got "x")"});
}

TEST_F(SceneBakeRecord, RecordBandsMustAgreeWithTransferAttributes) {
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  for (const char* name : {"_PRT_SH_00", "_PRT_SH_01", "_PRT_SH_02", "_PRT_SH_03"})
    prim["attributes"][name] = b.vec3(std::vector<float>(9, 0.25f));
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  Json record = olderRecord();
  record["bands"] = 2;
  b.doc["asset"]["extras"]["prt"] = record;
  const prt::Scene two = prt::loadScene(b.writeGlb(dir_ / "two.glb"));
  EXPECT_EQ(two.transferBands, 2);
  EXPECT_EQ(two.bakeRecord->bands, 2);
  b.doc["asset"]["extras"]["prt"]["bands"] = 3;
  expectError(b.writeGlb(dir_ / "three.glb"), {"asset.extras.prt.bands: 3, but the transfer attributes hold 2 bands"});
}

// A bake whose every instance is a receiver writes no transfer attribute: the scene's band
// count is the record's, so the receivers can be lit from probes baked with it.
TEST_F(SceneBakeRecord, ReceiversOnlyBakeTakesItsBandsFromTheRecord) {
  EXPECT_EQ(prt::loadScene(writeRecordScene(dir_ / "receivers.glb", olderRecord(), true)).transferBands, 3);
  // An instance that is not a receiver and has no transfer: simply not baked, no bands.
  EXPECT_EQ(prt::loadScene(writeRecordScene(dir_ / "unbaked.glb", olderRecord(), false)).transferBands, 0);
  EXPECT_EQ(prt::loadScene(writeRecordScene(dir_ / "no_record.glb", nullptr, true)).transferBands, 0);
}

// ---------------------------------------------------------------------------------------------
// What real files hold (issue 13): flat normals, KHR_texture_transform, spec-gloss, PNG kinds,
// percent-encoded URIs, unused meshes.

using SceneFlatNormals = SceneTest;

/// The cube [-1, 1]³, faces counter-clockwise seen from outside: 8 shared corners (`flat`) or
/// 24 vertices with their face normals (the same cube as an exporter with normals writes it).
GltfBuilder cube(bool withNormals) {
  std::vector<float> positions, normals;
  std::vector<uint32_t> indices;
  auto corner = [](const glm::vec3& p) { return uint32_t((p.x > 0) | (p.y > 0) << 1 | (p.z > 0) << 2); };
  if (!withNormals)
    for (uint32_t c = 0; c < 8; ++c)
      positions.insert(positions.end(), {c & 1 ? 1.f : -1.f, c & 2 ? 1.f : -1.f, c & 4 ? 1.f : -1.f});
  for (int axis = 0; axis < 3; ++axis) {
    for (float sign : {1.0f, -1.0f}) {
      glm::vec3 n(0.0f), u(0.0f), v(0.0f);
      n[axis] = sign;
      u[(axis + 1) % 3] = 1.0f;
      v[(axis + 2) % 3] = 1.0f;  // (u, v, n) right-handed for sign +1
      std::vector<glm::vec3> quad = {n - u - v, n + u - v, n + u + v, n - u + v};
      if (sign < 0) std::reverse(quad.begin(), quad.end());
      std::vector<uint32_t> ids;
      for (const glm::vec3& p : quad) {
        if (withNormals) {
          ids.push_back(uint32_t(positions.size() / 3));
          positions.insert(positions.end(), {p.x, p.y, p.z});
          normals.insert(normals.end(), {n.x, n.y, n.z});
        } else {
          ids.push_back(corner(p));
        }
      }
      indices.insert(indices.end(), {ids[0], ids[1], ids[2], ids[0], ids[2], ids[3]});
    }
  }
  GltfBuilder b;
  Json prim = {{"attributes", {{"POSITION", b.vec3(positions)}}}, {"indices", b.indices(indices)}};
  if (withNormals) prim["attributes"]["NORMAL"] = b.vec3(normals);
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}, {"scale", {1, 1, -1}}})});  // mirrored, to check winding
  return b;
}

/// Bakes `scene` unshadowed (closed form: transfer depends on the normal only) into its instances.
void bakeUnshadowed(prt::Scene& scene) {
  prt::bake::BakeSettings settings;
  settings.bands = 2;
  settings.shadowed = false;
  const prt::bake::SurfaceTransfer t = prt::bake::bakeSurface(scene, settings);
  for (size_t k = 0; k < scene.meshes.size(); ++k) scene.meshes[k].transfer = t.perMesh[k];
  scene.transferBands = t.bands;
}

TEST_F(SceneFlatNormals, CubeWithoutNormalsGetsFaceNormalsAndBakesAsWithThem) {
  const std::string flatPath = cube(false).write(dir_ / "flat_cube.gltf");
  prt::Scene flat = prt::loadScene(flatPath);
  prt::Scene given = prt::loadScene(cube(true).write(dir_ / "cube.gltf"));
  ASSERT_EQ(flat.meshes.size(), 1u);
  const prt::MeshInstance& f = flat.meshes[0];
  ASSERT_EQ(f.vertexCount(), 24u);  // each corner once per face it belongs to
  ASSERT_EQ(f.fileVertex.size(), 24u);
  ASSERT_EQ(f.triangleCount(), 12u);
  // Every face corner's normal is its face's, pointing away from the centre.
  for (size_t t = 0; t < f.triangleCount(); ++t) {
    const uint32_t* i = &f.indices[3 * t];
    const glm::vec3 face =
        glm::normalize(glm::cross(f.positions[i[1]] - f.positions[i[0]], f.positions[i[2]] - f.positions[i[0]]));
    for (int k = 0; k < 3; ++k) expectNear(f.normals[i[k]], face);
    EXPECT_GT(glm::dot(face, f.positions[i[0]]), 0.0f);
  }
  bakeUnshadowed(flat);
  bakeUnshadowed(given);
  // Same transfer at the same (position, normal), whatever the vertex order.
  const prt::MeshInstance& g = given.meshes[0];
  ASSERT_EQ(g.vertexCount(), 24u);
  for (size_t v = 0; v < 24; ++v) {
    size_t match = 24;
    for (size_t w = 0; w < 24; ++w)
      if (glm::length(g.positions[w] - f.positions[v]) < kTol && glm::length(g.normals[w] - f.normals[v]) < kTol)
        match = w;
    ASSERT_LT(match, 24u) << "vertex " << v;
    for (int c = 0; c < 4; ++c) expectNear(f.transferOf(v, 2)[c], g.transferOf(match, 2)[c]);
  }

  // The baked file holds the split vertices with their normals: read back, it has the
  // vertices the transfer belongs to.
  const fs::path out = dir_ / "flat_cube.glb";
  prt::writeBakedScene(flatPath, flat, nullptr, out.string());
  const prt::Scene baked = prt::loadScene(out.string());
  ASSERT_EQ(baked.meshes.size(), 1u);
  const prt::MeshInstance& b = baked.meshes[0];
  EXPECT_TRUE(b.fileVertex.empty());  // the file now has NORMAL: nothing to split
  ASSERT_EQ(b.vertexCount(), 24u);
  EXPECT_EQ(b.indices, f.indices);
  EXPECT_EQ(b.transfer, f.transfer);
  for (size_t v = 0; v < 24; ++v) {
    expectNear(b.positions[v], f.positions[v]);
    expectNear(b.normals[v], f.normals[v]);
  }
  const Json prim = glbJson(out)["meshes"][0]["primitives"][0];
  EXPECT_TRUE(prim["attributes"].contains("NORMAL"));
  EXPECT_EQ(glbJson(out)["accessors"][prim["attributes"]["POSITION"].get<int>()]["count"], 24);
}

TEST_F(SceneFlatNormals, CoplanarTrianglesKeepSharingVertices) {
  GltfBuilder b;
  // A quad of two triangles in one plane, with colours: no vertex needs splitting.
  Json prim = trianglePrimitive(b, {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0});
  prim["indices"] = b.indices({0, 1, 2, 0, 2, 3});
  prim["attributes"]["COLOR_0"] = b.floats({1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1}, "VEC3", 3);
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  const prt::Scene scene = prt::loadScene(b.write(dir_ / "quad.gltf"));
  const prt::MeshInstance& m = scene.meshes[0];
  EXPECT_EQ(m.vertexCount(), 4u);
  EXPECT_TRUE(m.fileVertex.empty());
  for (const glm::vec3& n : m.normals) expectNear(n, {0, 0, 1});
  EXPECT_EQ(m.colors[2], glm::vec4(0, 0, 1, 1));
}

using SceneTextureTransform = SceneTest;

/// 2×2 texture: red, green / blue, grey 188 (sRGB), REPEAT.
std::string quadrantsPng() {
  return encodePng(2, 2, {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 188, 188, 188, 255});
}

TEST_F(SceneTextureTransform, AlbedoIsTheTransformedLookupOnTheOverriddenTexCoord) {
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  prim["attributes"]["NORMAL"] = b.vec3({0, 0, 1, 0, 0, 1, 0, 0, 1});
  // TEXCOORD_0 would sample green everywhere; the transform's texCoord picks TEXCOORD_1.
  prim["attributes"]["TEXCOORD_0"] = b.floats({0.75f, 0.25f, 0.75f, 0.25f, 0.75f, 0.25f}, "VEC2", 2);
  const std::vector<float> uv1 = {0.5f, 0.5f, 1.5f, 0.5f, 0.5f, 1.5f};
  prim["attributes"]["TEXCOORD_1"] = b.floats(uv1, "VEC2", 2);
  prim["material"] = 0;
  const std::string png = quadrantsPng();
  b.doc["images"] = Json::array({{{"uri", "data:image/png;base64," + base64(png)}}});
  b.doc["textures"] = Json::array({{{"source", 0}}});
  // The specification's example: the lower-left quadrant, rotated 90°.
  Json transform = {{"offset", {0, 1}}, {"rotation", 1.57079632679}, {"scale", {0.5, 0.5}}, {"texCoord", 1}};
  b.doc["materials"] =
      Json::array({{{"pbrMetallicRoughness",
                     {{"metallicFactor", 0},
                      {"baseColorTexture", {{"index", 0}, {"extensions", {{"KHR_texture_transform", transform}}}}}}}}});
  b.doc["extensionsUsed"] = {"KHR_texture_transform"};
  b.doc["extensionsRequired"] = {"KHR_texture_transform"};
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  const prt::Scene scene = prt::loadScene(b.write(dir_ / "transform.gltf"));
  EXPECT_TRUE(scene.warnings.empty());
  const prt::MeshInstance& m = scene.meshes[0];
  ASSERT_EQ(scene.textures.size(), 1u);
  const prt::Texture& tex = scene.textures[0];
  // uv' = T·R·S·uv with R rotating counter-clockwise in the image (v down):
  // u' = 0.5 v, v' = 1 − 0.5 u for this transform.
  for (uint32_t v = 0; v < 3; ++v) {
    const glm::vec2 uv(uv1[2 * v], uv1[2 * v + 1]);
    const glm::vec2 expected(0.5f * uv.y, 1.0f - 0.5f * uv.x);
    expectNear(glm::vec3(m.texcoords[v], 0), glm::vec3(expected, 0));
    expectNear(prt::albedoAtVertex(scene, m, v), glm::vec3(tex.sample(expected)));
  }
  // Texel centres: vertex 0 lands on blue (lower left), 1 on red, 2 on grey.
  const float grey = float(srgbToLinearRef(188.0 / 255.0));
  expectNear(prt::albedoAtVertex(scene, m, 0), {0, 0, 1});
  expectNear(prt::albedoAtVertex(scene, m, 1), {1, 0, 0});
  expectNear(prt::albedoAtVertex(scene, m, 2), glm::vec3(grey));
  // Inside the triangle the transformed coordinates interpolate: the centroid's lookup.
  const glm::vec2 centroid = (glm::vec2(0.25f, 0.75f) + glm::vec2(0.25f, 0.25f) + glm::vec2(0.75f, 0.75f)) / 3.0f;
  expectNear(prt::albedoAt(scene, m, 0, 1.0f / 3, 1.0f / 3), glm::vec3(tex.sample(centroid)));
}

using SceneSpecularGlossiness = SceneTest;

TEST_F(SceneSpecularGlossiness, DiffuseFactorAndTextureAreTheAlbedo) {
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  prim["attributes"]["TEXCOORD_0"] = b.floats({0.25f, 0.5f, 0.75f, 0.5f, 0.75f, 0.5f}, "VEC2", 2);
  prim["material"] = 0;
  const std::string png = encodePng(2, 1, {255, 0, 0, 255, 0, 255, 0, 255});
  b.doc["images"] = Json::array({{{"uri", "data:image/png;base64," + base64(png)}}});
  b.doc["textures"] = Json::array({{{"source", 0}}});
  Json specGloss = {{"diffuseFactor", {0.5, 0.25, 1.0, 1.0}},
                    {"diffuseTexture", {{"index", 0}}},
                    {"specularFactor", {1, 1, 1}},
                    {"glossinessFactor", 0.5}};
  // The metallic-roughness colour is what a viewer without the extension shows; prt must not.
  b.doc["materials"] =
      Json::array({{{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {0.1, 0.1, 0.1, 1}}}},
                    {"extensions", {{"KHR_materials_pbrSpecularGlossiness", specGloss}}}}});
  b.doc["extensionsUsed"] = {"KHR_materials_pbrSpecularGlossiness"};
  b.doc["extensionsRequired"] = {"KHR_materials_pbrSpecularGlossiness"};
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  const prt::Scene scene = prt::loadScene(b.write(dir_ / "specgloss.gltf"));
  const prt::MeshInstance& m = scene.meshes[0];
  expectNear(prt::albedoAtVertex(scene, m, 0), {0.5f, 0, 0});
  expectNear(prt::albedoAtVertex(scene, m, 1), {0, 0.25f, 0});
}

using ScenePng = SceneTest;

/// A one-triangle scene textured with `png`, its three vertices at the centres of texels 0, 1, 2
/// of a 3×1 image.
prt::Scene loadWithTexture(const fs::path& dir, const std::string& png) {
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  prim["attributes"]["TEXCOORD_0"] = b.floats({0.5f / 3, 0.5f, 1.5f / 3, 0.5f, 2.5f / 3, 0.5f}, "VEC2", 2);
  prim["material"] = 0;
  b.doc["images"] = Json::array({{{"uri", "data:image/png;base64," + base64(png)}}});
  b.doc["textures"] = Json::array({{{"source", 0}}});
  b.doc["materials"] =
      Json::array({{{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorTexture", {{"index", 0}}}}}}});
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  return prt::loadScene(b.write(dir / "png.gltf"));
}

TEST_F(ScenePng, SixteenBitSamplesKeepTheirPrecision) {
  // RGBA, 16 bits a sample, big-endian. 1000/65535 and 40000/65535 fall between 8-bit steps,
  // so a decoder that dropped the low byte would miss them by up to 1/255 before sRGB decoding.
  const std::vector<uint16_t> samples = {1000, 40000, 65535, 65535, 0, 12345, 257, 32768, 65535, 1, 0, 0};
  std::vector<uint8_t> rows;
  for (uint16_t v : samples) rows.insert(rows.end(), {uint8_t(v >> 8), uint8_t(v & 0xFF)});
  const prt::Scene scene = loadWithTexture(dir_, encodePngRaw(3, 1, 16, 6, rows, 3 * 8));
  ASSERT_EQ(scene.textures.size(), 1u);
  const prt::Texture& tex = scene.textures[0];
  ASSERT_EQ(tex.width, 3);
  for (size_t t = 0; t < 3; ++t)
    for (int c = 0; c < 4; ++c) {
      const double x = samples[4 * t + size_t(c)] / 65535.0;
      const double expected = c < 3 ? srgbToLinearRef(x) : x;  // colour is sRGB, alpha linear
      EXPECT_NEAR(tex.texels[t][c], expected, 1e-6) << "texel " << t << " channel " << c;
    }
}

TEST_F(ScenePng, PaletteWithTransparencyReadsItsColours) {
  // 4-bit palette indices 2, 0, 1 (two to a byte); tRNS gives entry 0 alpha 128, entry 1
  // alpha 0, entry 2 none (opaque).
  const std::string plte(
      "\xC8\x64\x0A"
      "\x00\x80\xFF"
      "\xFF\xFF\xFF",
      9);
  const std::string trns("\x80\x00", 2);
  const std::vector<uint8_t> rows = {0x20, 0x10};
  const std::string png = encodePngRaw(3, 1, 4, 3, rows, 2, pngChunk("PLTE", plte) + pngChunk("tRNS", trns));
  const prt::Scene scene = loadWithTexture(dir_, png);
  ASSERT_EQ(scene.textures.size(), 1u);
  const prt::Texture& tex = scene.textures[0];
  ASSERT_EQ(tex.width, 3);
  auto expected = [](int r, int g, int b, int a) {
    return glm::vec4(srgbToLinearRef(r / 255.0), srgbToLinearRef(g / 255.0), srgbToLinearRef(b / 255.0), a / 255.0);
  };
  const glm::vec4 want[3] = {expected(255, 255, 255, 255), expected(200, 100, 10, 128), expected(0, 128, 255, 0)};
  for (size_t t = 0; t < 3; ++t)
    for (int c = 0; c < 4; ++c) EXPECT_NEAR(tex.texels[t][c], want[t][c], 1e-6) << "texel " << t << " channel " << c;
  expectNear(prt::albedoAtVertex(scene, scene.meshes[0], 1), glm::vec3(want[1]));
}

using SceneUri = SceneTest;

TEST_F(SceneUri, PercentEncodedImageUriIsDecoded) {
  const std::string png = quadrantsPng();
  fs::create_directories(dir_ / "tex dir");
  std::ofstream(dir_ / "tex dir" / "a b+c.png", std::ios::binary) << png;
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  prim["attributes"]["TEXCOORD_0"] = b.floats({0.25f, 0.25f, 0.75f, 0.25f, 0.25f, 0.75f}, "VEC2", 2);
  prim["material"] = 0;
  // RFC 3986: space as %20, the folder separator as %2F, '+' as %2B.
  b.doc["images"] = Json::array({{{"uri", "tex%20dir%2Fa%20b%2Bc.png"}}});
  b.doc["textures"] = Json::array({{{"source", 0}}});
  b.doc["materials"] =
      Json::array({{{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorTexture", {{"index", 0}}}}}}});
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  const prt::Scene scene = prt::loadScene(b.write(dir_ / "encoded.gltf"));
  ASSERT_EQ(scene.textures.size(), 1u);
  expectNear(prt::albedoAtVertex(scene, scene.meshes[0], 0), {1, 0, 0});
  expectNear(prt::albedoAtVertex(scene, scene.meshes[0], 1), {0, 1, 0});
}

TEST_F(SceneUri, PercentEncodedDotsStillCannotLeaveTheFolder) {
  fs::create_directories(dir_ / "scene");
  std::ofstream(dir_ / "outside.png", std::ios::binary) << quadrantsPng();
  GltfBuilder b;
  Json prim = trianglePrimitive(b);
  prim["attributes"]["TEXCOORD_0"] = b.floats({0.25f, 0.25f, 0.75f, 0.25f, 0.25f, 0.75f}, "VEC2", 2);
  prim["material"] = 0;
  b.doc["images"] = Json::array({{{"uri", "%2E%2E%2Foutside.png"}}});
  b.doc["textures"] = Json::array({{{"source", 0}}});
  b.doc["materials"] =
      Json::array({{{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorTexture", {{"index", 0}}}}}}});
  b.scene({b.node({{"mesh", b.mesh(Json::array({prim}))}})});
  const std::string path = b.write(dir_ / "scene" / "escape.gltf");
  try {
    prt::loadScene(path);
    ADD_FAILURE() << "an encoded ../ was read";
  } catch (const prt::ExternalUriRefused& e) {
    EXPECT_NE(std::string(e.what()).find("image 0: uri '%2E%2E%2Foutside.png' points outside the scene folder"),
              std::string::npos)
        << e.what();
  }
}

using SceneUnusedMesh = SceneTest;

TEST_F(SceneUnusedMesh, IsIgnoredByLoadingAndWriting) {
  GltfBuilder b;
  const int used = b.mesh(Json::array({trianglePrimitive(b)}));
  // Mesh 1, which no node uses: a fan whose indices run past its vertices, and a material
  // whose texture's image does not exist. Either would be an error in a mesh of the scene.
  Json broken = trianglePrimitive(b);
  broken["mode"] = 6;
  broken["indices"] = b.indices({0, 1, 7});
  broken["material"] = 0;
  b.mesh(Json::array({broken}));
  b.doc["textures"] = Json::array({{{"source", 5}}});
  b.doc["materials"] =
      Json::array({{{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorTexture", {{"index", 0}}}}}}});
  b.scene({b.node({{"mesh", used}})});
  const std::string input = b.write(dir_ / "unused.gltf");
  prt::Scene scene = prt::loadScene(input);
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_EQ(scene.meshes[0].mesh, used);
  EXPECT_TRUE(scene.textures.empty());
  EXPECT_TRUE(scene.warnings.empty());
  fillTransfer(scene, 1);
  const fs::path out = dir_ / "unused.glb";
  prt::writeBakedScene(input, scene, nullptr, out.string());
  const prt::Scene baked = prt::loadScene(out.string());
  ASSERT_EQ(baked.meshes.size(), 1u);
  EXPECT_EQ(baked.meshes[0].transfer, scene.meshes[0].transfer);
  EXPECT_EQ(glbJson(out)["meshes"].size(), 2u);  // passed through untouched
}

}  // namespace
