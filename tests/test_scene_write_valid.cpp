// The files writeBakedScene and writeLitScene write are valid glTF, on the points where the
// Khronos glTF Validator once found errors (CliGltfValidator, tests/cli_gltf_validator.sh,
// runs the validator itself on prt's outputs): a camera's zfar is positive or absent, COLOR_0
// stays in 0..1 while _RADIANCE keeps the exact radiance, accessor bounds are the data's, and a
// .gltf output is glTF JSON.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gltf_file.h"
#include "harness.h"
#include "prt/scene.h"
#include "test_scenes.h"

namespace prt {
namespace {

using Json = nlohmann::json;
using test::Glb;

/// A 2 × 2 plane (NORMAL, TEXCOORD_0) seen by a perspective camera whose zfar is `zfar`
/// (0: the file leaves it out, an infinite projection).
std::string planeUnderCamera(const test::TempDir& d, double zfar) {
  test::GltfFile f;
  const MeshInstance plane = test::makePlane({0, 0, 0}, 2.0f, 2);
  const int mesh = f.mesh(plane);
  std::vector<float> uv;
  for (const glm::vec3& p : plane.positions) uv.insert(uv.end(), {(p.x + 1) / 2, (p.z + 1) / 2});
  const int uvAccessor = f.accessor(uv, "VEC2");
  f.j["accessors"][size_t(uvAccessor)]["count"] = plane.vertexCount();
  f.j["meshes"][size_t(mesh)]["primitives"][0]["attributes"]["TEXCOORD_0"] = uvAccessor;
  Json perspective = {{"yfov", 0.8}, {"znear", 0.1}};
  if (zfar > 0.0) perspective["zfar"] = zfar;
  f.j["cameras"] = Json::array({{{"type", "perspective"}, {"perspective", perspective}}});
  f.node({{"name", "Plane"}, {"mesh", mesh}}, true);
  f.node({{"name", "Camera"}, {"camera", 0}, {"translation", {0.0, 1.0, 3.0}}}, true);
  return f.write(zfar > 0.0 ? "finite_camera" : "infinite_camera", d.path());
}

/// The glTF JSON of a written file, .glb or .gltf.
Json documentOf(const std::string& path) {
  if (path.ends_with(".glb")) return Glb(path).j;
  return Json::parse(test::fileBytes(path));
}

/// Radiance per vertex of every instance, values a viewer cannot show among them: above 1,
/// below 0 (a ringing SH estimate), tiny.
std::vector<std::vector<glm::vec3>> radianceOf(const Scene& s) {
  const float values[] = {2.5f, -1e-3f, 0.5f, 1.0f, 7.25f, 1e-8f, 0.0f, 1.0000001f, 0.999f};
  std::vector<std::vector<glm::vec3>> radiance(s.meshes.size());
  for (size_t k = 0; k < s.meshes.size(); ++k)
    for (size_t v = 0; v < s.meshes[k].vertexCount(); ++v)
      radiance[k].push_back(glm::vec3(values[v % 9], values[(v + 3) % 9], values[(v + 7) % 9]));
  return radiance;
}

// An infinite camera (zfar 0 in prt::Camera and tinygltf) is written without zfar, a finite
// one keeps its zfar; either reads back as it was, from every kind of file prt writes.
TEST(SceneWriteValid, CameraZfarIsPositiveOrAbsentAndReadsBack) {
  const test::TempDir d;
  for (double zfar : {0.0, 50.0}) {
    const std::string input = planeUnderCamera(d, zfar);
    const Scene s = loadScene(input);
    ASSERT_EQ(s.cameras.size(), 1u);
    EXPECT_EQ(s.cameras[0].zfar, zfar);
    const std::string tag = zfar > 0.0 ? "finite" : "infinite";
    const std::vector<std::string> outputs = {d.file(tag + "_baked.glb"), d.file(tag + "_baked.gltf"),
                                              d.file(tag + "_lit.glb"), d.file(tag + "_lit.gltf")};
    writeBakedScene(input, s, nullptr, outputs[0]);
    writeBakedScene(input, s, nullptr, outputs[1]);
    writeLitScene(input, s, radianceOf(s), outputs[2]);
    writeLitScene(input, s, radianceOf(s), outputs[3]);
    for (const std::string& out : outputs) {
      const Json perspective = documentOf(out).at("cameras").at(0).at("perspective");
      if (zfar > 0.0)
        EXPECT_EQ(perspective.value("zfar", -1.0), zfar) << out;
      else
        EXPECT_FALSE(perspective.contains("zfar")) << out;
      EXPECT_EQ(perspective.at("znear").get<double>(), 0.1) << out;
      const Scene back = loadScene(out);
      ASSERT_EQ(back.cameras.size(), 1u) << out;
      EXPECT_EQ(back.cameras[0].zfar, zfar) << out;
      EXPECT_EQ(back.cameras[0].yfov, 0.8) << out;
    }
  }
}

// _RADIANCE holds the radiance bit for bit; COLOR_0 the same clamped to 0..1 (glTF's range for
// it), which loadScene then reads as the vertex colour; texture coordinates are gone with the
// textures.
TEST(SceneWriteValid, LitFileKeepsExactRadianceAndClampsColor0) {
  const test::TempDir d;
  const std::string input = planeUnderCamera(d, 0.0), lit = d.file("lit.glb");
  const Scene s = loadScene(input);
  const std::vector<std::vector<glm::vec3>> radiance = radianceOf(s);
  writeLitScene(input, s, radiance, lit);

  const Glb glb(lit);
  const Json& attributes = glb.primitive("Plane").at("attributes");
  EXPECT_FALSE(attributes.contains("TEXCOORD_0"));
  for (const char* name : {"_RADIANCE", "COLOR_0"}) {
    const Json& accessor = glb.j["accessors"][attributes.at(name).get<size_t>()];
    EXPECT_EQ(accessor["type"], "VEC3") << name;
    EXPECT_EQ(accessor["componentType"], 5126) << name;  // FLOAT
  }
  const std::vector<float> exact = glb.values<float>(attributes["_RADIANCE"].get<int>(), 3);
  const std::vector<float> shown = glb.values<float>(attributes["COLOR_0"].get<int>(), 3);
  ASSERT_EQ(exact.size(), radiance[0].size() * 3);
  ASSERT_EQ(shown.size(), exact.size());
  EXPECT_EQ(std::memcmp(exact.data(), radiance[0].data(), exact.size() * sizeof(float)), 0);
  for (size_t i = 0; i < shown.size(); ++i) {
    EXPECT_GE(shown[i], 0.0f) << i;
    EXPECT_LE(shown[i], 1.0f) << i;
    EXPECT_EQ(shown[i], std::clamp(exact[i], 0.0f, 1.0f)) << i;
  }

  const Scene back = loadScene(lit);
  ASSERT_EQ(back.meshes.size(), 1u);
  ASSERT_EQ(back.meshes[0].colors.size(), radiance[0].size());
  for (size_t v = 0; v < radiance[0].size(); ++v)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(back.meshes[0].colors[v][c], shown[v * 3 + size_t(c)]);
}

// A .gltf output is glTF JSON with its one buffer inline; the transfer reads back bit for bit.
TEST(SceneWriteValid, GltfOutputIsJsonWithItsBufferInline) {
  const test::TempDir d;
  const std::string input = planeUnderCamera(d, 0.0), out = d.file("baked.gltf");
  Scene s = loadScene(input);
  s.transferBands = 2;
  for (MeshInstance& m : s.meshes)
    for (size_t i = 0; i < m.vertexCount() * 4; ++i) m.transfer.push_back(glm::vec3(float(i), 0.25f, -1.5f));
  writeBakedScene(input, s, nullptr, out);
  const std::string bytes = test::fileBytes(out);
  ASSERT_FALSE(bytes.empty());
  EXPECT_EQ(bytes[0], '{');
  const Json doc = Json::parse(bytes);
  ASSERT_EQ(doc.at("buffers").size(), 1u);
  EXPECT_TRUE(doc["buffers"][0].at("uri").get<std::string>().starts_with("data:application/octet-stream;base64,"));
  const Scene back = loadScene(out);
  ASSERT_EQ(back.meshes.size(), 1u);
  EXPECT_EQ(back.transferBands, 2);
  ASSERT_EQ(back.meshes[0].transfer.size(), s.meshes[0].transfer.size());
  EXPECT_EQ(std::memcmp(back.meshes[0].transfer.data(), s.meshes[0].transfer.data(),
                        s.meshes[0].transfer.size() * sizeof(glm::vec3)),
            0);
}

// Declared bounds that are not the data's (as Draco-decoded files carry: the values before
// quantisation, the indices before reordering) are written as the data's.
TEST(SceneWriteValid, AccessorBoundsAreTheData) {
  const test::TempDir d;
  test::GltfFile f;
  const MeshInstance plane = test::makePlane({0, 0, 0}, 2.0f, 2);  // x, z in -1..1; indices 0..8
  const int mesh = f.mesh(plane);
  const Json& prim = f.j["meshes"][size_t(mesh)]["primitives"][0];
  Json& position = f.j["accessors"][prim["attributes"]["POSITION"].get<size_t>()];
  position["min"] = {-1.0078, 0.0, -1.0};
  position["max"] = {1.0, 0.5, 1.0};
  f.j["accessors"][prim["indices"].get<size_t>()]["max"] = {11};
  f.j["accessors"][prim["indices"].get<size_t>()]["min"] = {0};
  f.node({{"name", "Plane"}, {"mesh", mesh}}, true);
  const std::string input = f.write("bounds", d.path()), out = d.file("baked.glb");
  writeBakedScene(input, loadScene(input), nullptr, out);
  const Glb glb(out);
  const Json& written = glb.primitive("Plane");
  const Json& p = glb.j["accessors"][written["attributes"]["POSITION"].get<size_t>()];
  EXPECT_EQ(p["min"], Json::array({-1.0, 0.0, -1.0}));
  EXPECT_EQ(p["max"], Json::array({1.0, 0.0, 1.0}));
  const Json& indices = glb.j["accessors"][written["indices"].get<size_t>()];
  EXPECT_EQ(indices["min"], Json::array({0}));
  EXPECT_EQ(indices["max"], Json::array({8}));
}

// The .glb framing: the header's length is the file's, both chunks 4-byte multiples, the BIN
// chunk the buffer's bytes with at most 3 bytes of padding.
TEST(SceneWriteValid, GlbChunksAreAlignedAndSized) {
  const test::TempDir d;
  const std::string input = planeUnderCamera(d, 0.0), out = d.file("baked.glb");
  writeBakedScene(input, loadScene(input), nullptr, out);
  const std::string bytes = test::fileBytes(out);
  ASSERT_GE(bytes.size(), 28u);
  auto word = [&](size_t at) {
    uint32_t v = 0;
    std::memcpy(&v, bytes.data() + at, 4);
    return v;
  };
  EXPECT_EQ(bytes.substr(0, 4), "glTF");
  EXPECT_EQ(word(4), 2u);
  EXPECT_EQ(word(8), bytes.size());
  const uint32_t jsonLength = word(12);
  EXPECT_EQ(bytes.substr(16, 4), "JSON");
  EXPECT_EQ(jsonLength % 4, 0u);
  ASSERT_LE(28u + jsonLength, bytes.size());
  const uint32_t binLength = word(20 + jsonLength);
  EXPECT_EQ(bytes.substr(24 + jsonLength, 4), std::string("BIN\0", 4));
  EXPECT_EQ(binLength % 4, 0u);
  EXPECT_EQ(28u + jsonLength + binLength, bytes.size());
  const size_t byteLength = Glb(out).j.at("buffers").at(0).at("byteLength").get<size_t>();
  EXPECT_LE(byteLength, binLength);
  EXPECT_LT(binLength - byteLength, 4u);
  EXPECT_FALSE(Glb(out).j["buffers"][0].contains("uri"));
}

}  // namespace
}  // namespace prt
