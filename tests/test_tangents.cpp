// MikkTSpace tangents (prt/tangents.h) by their properties: unit and orthogonal to the normal,
// the U direction on a plane whose coordinates follow its axes, handedness that flips with
// mirrored coordinates, a frame that turns with the coordinates, a fallback frame and no NaN
// for degenerate coordinates; and the loader's use of them (TANGENT read, transformed with
// the node, generated where a normal texture needs them, with a warning naming the material).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "gltf_file.h"
#include "harness.h"
#include "png_file.h"
#include "prt/math.h"
#include "prt/scene.h"
#include "prt/tangents.h"
#include "test_scenes.h"

namespace prt {
namespace {

using Json = nlohmann::json;

/// An n × n grid of quads in the plane z = 0 facing +Z, positions (x, y) ∈ [0, 1]², texture
/// coordinates `uv(x, y)`.
struct Grid {
  std::vector<glm::vec3> positions, normals;
  std::vector<glm::vec2> uvs;
  std::vector<uint32_t> indices;
};
template <class Uv>
Grid makeGrid(int n, Uv uv) {
  Grid g;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const float x = float(i) / n, y = float(j) / n;
      g.positions.push_back({x, y, 0.0f});
      g.normals.push_back({0.0f, 0.0f, 1.0f});
      g.uvs.push_back(uv(x, y));
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
      g.indices.insert(g.indices.end(), {a, b, d, a, d, c});  // counter-clockwise seen from +Z
    }
  return g;
}

TangentResult tangentsOf(const Grid& g) { return generateTangents(g.positions, g.normals, g.uvs, g.indices); }

void expectFrame(const glm::vec4& t, const glm::vec3& n) {
  EXPECT_TRUE(std::isfinite(t.x) && std::isfinite(t.y) && std::isfinite(t.z) && std::isfinite(t.w));
  EXPECT_NEAR(glm::length(glm::vec3(t)), 1.0f, 1e-5f);
  EXPECT_NEAR(glm::dot(glm::vec3(t), n), 0.0f, 1e-5f);
  EXPECT_EQ(std::abs(t.w), 1.0f);
}

// u along +x, v down the image along −y (glTF's convention for a texture seen upright): the
// tangent is +x, handedness +1, so the bitangent w (n × t) = +y points up the image.
TEST(SceneTangents, AxisAlignedCoordinatesGiveTheUDirection) {
  const TangentResult r = tangentsOf(makeGrid(4, [](float x, float y) { return glm::vec2(x, 1.0f - y); }));
  EXPECT_EQ(r.degenerateVertices, 0u);
  for (const glm::vec4& t : r.tangents) {
    expectFrame(t, {0, 0, 1});
    EXPECT_NEAR(t.x, 1.0f, 1e-6f);
    EXPECT_EQ(t.w, 1.0f);
  }
  // Scaled coordinates change nothing; u along +y makes the tangent +y.
  for (const glm::vec4& t :
       tangentsOf(makeGrid(3, [](float x, float y) { return glm::vec2(4.0f * x, 2.0f - y); })).tangents)
    EXPECT_NEAR(t.x, 1.0f, 1e-6f);
  for (const glm::vec4& t : tangentsOf(makeGrid(3, [](float x, float y) { return glm::vec2(y, x); })).tangents)
    EXPECT_NEAR(t.y, 1.0f, 1e-6f);
}

// Mirroring u (u = 1 − x) turns the tangent to −x and flips the handedness, so the bitangent
// still points up the image; mirroring v alone keeps the tangent and flips the handedness.
TEST(SceneTangents, MirroredCoordinatesFlipTheHandedness) {
  for (const glm::vec4& t :
       tangentsOf(makeGrid(4, [](float x, float y) { return glm::vec2(1.0f - x, 1.0f - y); })).tangents) {
    expectFrame(t, {0, 0, 1});
    EXPECT_NEAR(t.x, -1.0f, 1e-6f);
    EXPECT_EQ(t.w, -1.0f);
    EXPECT_NEAR((t.w * glm::cross(glm::vec3(0, 0, 1), glm::vec3(t))).y, 1.0f, 1e-6f);
  }
  for (const glm::vec4& t : tangentsOf(makeGrid(4, [](float x, float y) { return glm::vec2(x, y); })).tangents) {
    EXPECT_NEAR(t.x, 1.0f, 1e-6f);
    EXPECT_EQ(t.w, -1.0f);
  }
}

// Coordinates turned by θ: (u, 1 − v) = R(θ)(x, y), so u = cos θ x − sin θ y. For a rotation
// the direction of increasing u at constant v is u's gradient, (cos θ, −sin θ): the tangent
// turns by −θ as the coordinates turn by θ, and the handedness stays +1.
TEST(SceneTangents, FrameTurnsWithTheCoordinates) {
  for (double deg : {0.0, 30.0, 90.0, 135.0, 250.0}) {
    const float th = float(deg * kPi / 180.0), c = std::cos(th), s = std::sin(th);
    // (u, 1 − v) = R(θ) (x, y): MikkTSpace's frame, written back in glTF's v.
    const Grid g = makeGrid(3, [&](float x, float y) { return glm::vec2(c * x - s * y, 1.0f - (s * x + c * y)); });
    for (const glm::vec4& t : tangentsOf(g).tangents) {
      expectFrame(t, {0, 0, 1});
      EXPECT_NEAR(t.x, c, 1e-5f) << deg;
      EXPECT_NEAR(t.y, -s, 1e-5f) << deg;
      EXPECT_EQ(t.w, 1.0f);
    }
  }
}

// A curved surface: per-vertex normals of a cavity (a sphere with an opening), coordinates
// from longitude and latitude: every tangent unit and orthogonal to its vertex's normal.
TEST(SceneTangents, CurvedSurfaceFramesAreOrthonormal) {
  const MeshInstance m = test::makeCavity(0.6, 12, 24);
  std::vector<glm::vec2> uv;
  for (const glm::vec3& p : m.positions) {
    const glm::vec3 d = glm::normalize(p);
    uv.push_back({std::atan2(d.z, d.x) / float(2 * kPi) + 0.5f, std::acos(std::clamp(d.y, -1.0f, 1.0f)) / float(kPi)});
  }
  const TangentResult r = generateTangents(m.positions, m.normals, uv, m.indices);
  for (size_t v = 0; v < m.vertexCount(); ++v) expectFrame(r.tangents[v], m.normals[v]);
}

// Degenerate coordinates (every vertex at one uv, or non-finite): the fallback frame, counted,
// never NaN; a zero-area triangle among good ones does not disturb its neighbours.
TEST(SceneTangents, DegenerateCoordinatesGiveAFallbackFrameNeverNaN) {
  Grid g = makeGrid(2, [](float, float) { return glm::vec2(0.5f, 0.5f); });
  TangentResult r = tangentsOf(g);
  EXPECT_EQ(r.degenerateVertices, g.positions.size());
  for (const glm::vec4& t : r.tangents) expectFrame(t, {0, 0, 1});
  g = makeGrid(2, [](float x, float y) { return glm::vec2(x, 1.0f - y); });
  g.uvs[4] = glm::vec2(NAN, 0.0f);
  r = tangentsOf(g);
  for (const glm::vec4& t : r.tangents) expectFrame(t, {0, 0, 1});
  EXPECT_NEAR(r.tangents[0].x, 1.0f, 1e-6f);  // vertex 0's triangles do not touch vertex 4
  for (const glm::vec3& n : {glm::vec3(0, 0, -1), glm::vec3(0, 1, 0), glm::normalize(glm::vec3(1, -2, 3))})
    expectFrame(glm::vec4(anyTangent(n), 1.0f), n);
}

// ---- The loader

int vec2Accessor(test::GltfFile& f, const std::vector<float>& data) { return f.accessor(data, "VEC2"); }

/// A unit quad in z = 0 facing +Z with u = x, v = 1 − y, a normal texture, optionally TANGENT
/// (xyzw for every vertex) and degenerate coordinates; node `node` places it.
std::string writeQuad(const test::TempDir& dir, const std::string& name, Json node, std::vector<float> tangent = {},
                      bool degenerate = false) {
  test::GltfFile f;
  f.j["images"] =
      Json::array({{{"uri", "data:image/png;base64," + test::base64(test::encodePng(1, 1, {128, 128, 255, 255}))}}});
  f.j["textures"] = Json::array({{{"source", 0}}});
  f.j["materials"] = Json::array({{{"name", "Relief"}, {"normalTexture", {{"index", 0}}}}});
  const std::vector<float> uv = degenerate ? std::vector<float>(8, 0.25f) : std::vector<float>{0, 1, 1, 1, 1, 0, 0, 0};
  Json attributes = {{"POSITION", f.accessor({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, "VEC3")},
                     {"NORMAL", f.accessor({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}, "VEC3")},
                     {"TEXCOORD_0", vec2Accessor(f, uv)}};
  if (!tangent.empty()) attributes["TANGENT"] = f.accessor(tangent, "VEC4");
  Json prim = {{"attributes", attributes},
               {"indices", f.accessor<uint32_t>({0, 1, 2, 0, 2, 3}, "SCALAR", 5125)},
               {"material", 0}};
  f.j["meshes"].push_back({{"primitives", Json::array({prim})}});
  node["mesh"] = f.j["meshes"].size() - 1;
  f.node(node, true);
  return f.write(name, dir.path());
}

TEST(SceneTangents, LoaderGeneratesReadsAndTransformsThem) {
  test::TempDir dir;
  // Generated: +x, handedness +1; the node turns it with the surface (90° about Z: +y).
  Scene s = loadScene(writeQuad(dir, "gen", Json::object()));
  ASSERT_EQ(s.meshes[0].tangents.size(), 4u);
  for (const glm::vec4& t : s.meshes[0].tangents) EXPECT_NEAR(glm::distance(t, glm::vec4(1, 0, 0, 1)), 0.0f, 1e-6f);
  const float h = std::sqrt(0.5f);
  s = loadScene(writeQuad(dir, "turned", {{"rotation", {0, 0, h, h}}}));
  for (const glm::vec4& t : s.meshes[0].tangents) EXPECT_NEAR(glm::distance(t, glm::vec4(0, 1, 0, 1)), 0.0f, 1e-6f);
  // The file's TANGENT wins (here −y with handedness −1, a frame of its own), made orthogonal
  // to the normal; a mirroring node flips the handedness.
  const std::vector<float> given = {0, -1, 0.5f, -1, 0, -1, 0.5f, -1, 0, -1, 0.5f, -1, 0, -1, 0.5f, -1};
  s = loadScene(writeQuad(dir, "given", Json::object(), given));
  for (const glm::vec4& t : s.meshes[0].tangents) EXPECT_NEAR(glm::distance(t, glm::vec4(0, -1, 0, -1)), 0.0f, 1e-6f);
  s = loadScene(writeQuad(dir, "mirrored", {{"scale", {-1, 1, 1}}}, given));
  for (const glm::vec4& t : s.meshes[0].tangents) EXPECT_NEAR(glm::distance(t, glm::vec4(0, -1, 0, 1)), 0.0f, 1e-6f);
  EXPECT_TRUE(s.warnings.empty());
}

TEST(SceneTangents, DegenerateCoordinatesWarnNamingTheMaterial) {
  test::TempDir dir;
  const Scene s = loadScene(writeQuad(dir, "degenerate", Json::object(), {}, true));
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("material 0 'Relief'"), std::string::npos) << s.warnings[0];
  EXPECT_NE(s.warnings[0].find("4 of 4 vertices have degenerate texture coordinates"), std::string::npos)
      << s.warnings[0];
  for (const glm::vec4& t : s.meshes[0].tangents) expectFrame(t, s.meshes[0].normals[0]);
}

}  // namespace
}  // namespace prt
