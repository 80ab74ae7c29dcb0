// Materials as light sees them (issue 13): alphaMode MASK cutouts, BLEND and
// KHR_materials_transmission partial occluders, loaded from small glTF files written here and
// baked against closed forms: the view factor (surfaces) and solid angle (probes) of the
// rectangles that block the sky.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "gltf_file.h"
#include "harness.h"
#include "png_file.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/sampling.h"
#include "prt/bake/surface_bake.h"
#include "prt/brdf.h"
#include "prt/error.h"
#include "prt/math.h"
#include "prt/scene.h"
#include "prt/sh.h"
#include "test_scenes.h"
#include "test_util.h"

namespace prt {
namespace {

using Json = nlohmann::json;

// ---- Closed forms for a rectangle [x0, x1] × [z0, z1] in the plane y = h, seen from the origin
// (a point of the plane y = 0), by inclusion-exclusion of a corner function that is odd in
// each coordinate.

/// View factor from a differential area at the origin facing +Y to the rectangle from the
/// origin's foot to (x, z) (Howell's catalogue, B-3).
double cornerViewFactor(double x, double z, double h) {
  const double a = x / h, b = z / h, sa = std::sqrt(1.0 + a * a), sb = std::sqrt(1.0 + b * b);
  return (a / sa * std::atan(b / sa) + b / sb * std::atan(a / sb)) / (2.0 * prt::kPi);
}

/// Solid angle of that rectangle from the origin.
double cornerSolidAngle(double x, double z, double h) {
  const double a = x / h, b = z / h;
  return std::atan(a * b / std::sqrt(1.0 + a * a + b * b));
}

template <class Corner>
double rectangle(Corner corner, double x0, double x1, double z0, double z1, double h) {
  return corner(x1, z1, h) - corner(x0, z1, h) - corner(x1, z0, h) + corner(x0, z0, h);
}

// The occluder of every test: a square of half-side kHalf at height kHeight above the floor,
// facing down. The checker cells have side kCell: 32 × 32 cells, fine next to the height, so
// the open fraction is close to half, but the tests sum the exact cells.
constexpr float kHalf = 4.0f, kHeight = 1.0f, kCell = 0.25f;
constexpr int kCells = int(2 * kHalf / kCell);

/// Sum of `corner` over the checker cells that are solid (i + j even, cell (0, 0) at x = z = −kHalf),
/// or over the whole square (`all`), seen from (px, y, pz) at distance h below the plane.
template <class Corner>
double overCells(Corner corner, double px, double pz, double h, bool all) {
  double sum = 0.0;
  for (int j = 0; j < kCells; ++j)
    for (int i = 0; i < kCells; ++i) {
      if (!all && (i + j) % 2) continue;
      const double x0 = -kHalf + i * kCell - px, z0 = -kHalf + j * kCell - pz;
      sum += rectangle(corner, x0, x0 + kCell, z0, z0 + kCell, h);
    }
  return sum;
}

// ---- Scenes as glTF files.

int vec2Accessor(test::GltfFile& f, const std::vector<float>& data) { return f.accessor(data, "VEC2"); }

/// The occluder square facing down, TEXCOORD_0 = (x + kHalf, z + kHalf) / (2 kCell) (one
/// repeat of a 2×2 texture covers 2×2 cells) or, given, (x + kHalf, z + kHalf) · uvScale;
/// placed by a root node.
void addOccluder(test::GltfFile& f, int material, float height = kHeight, float uvScale = 0.5f / kCell) {
  const float a = kHalf, u = 2 * a * uvScale;
  const std::vector<float> positions = {-a, height, -a, a, height, -a, a, height, a, -a, height, a};
  const std::vector<float> normals = {0, -1, 0, 0, -1, 0, 0, -1, 0, 0, -1, 0};
  const std::vector<float> uv = {0, 0, u, 0, u, u, 0, u};
  Json prim = {{"attributes",
                {{"POSITION", f.accessor(positions, "VEC3")},
                 {"NORMAL", f.accessor(normals, "VEC3")},
                 {"TEXCOORD_0", vec2Accessor(f, uv)}}},
               {"indices", f.accessor<uint32_t>({0, 1, 2, 0, 2, 3}, "SCALAR", 5125)},
               {"material", material}};
  f.j["meshes"].push_back({{"primitives", Json::array({prim})}});
  f.node({{"mesh", f.j["meshes"].size() - 1}}, true);
}

/// The floor: 2 × 2 at y = 0, facing up, 4 × 4 quads (25 vertices at x, z ∈ {−1, −½, 0, ½, 1}).
void addFloor(test::GltfFile& f, int material = -1) {
  f.node({{"mesh", f.mesh(test::makePlane({0, 0, 0}, 2.0f, 4), material)}}, true);
}

/// A 2×2 RGBA8 texture as image, sampler (REPEAT, or CLAMP_TO_EDGE) and texture 0: texels
/// (0,0) and (1,1) get alpha a11, the other two a01; RGB `rgb`.
void addTexture(test::GltfFile& f, uint8_t rgb, uint8_t a11, uint8_t a01, bool clamp = false) {
  const std::string png =
      test::encodePng(2, 2, {rgb, rgb, rgb, a11, rgb, rgb, rgb, a01, rgb, rgb, rgb, a01, rgb, rgb, rgb, a11});
  f.j["images"].push_back({{"uri", "data:image/png;base64," + test::base64(png)}});
  const int wrap = clamp ? 33071 : 10497;
  f.j["samplers"] = Json::array({{{"wrapS", wrap}, {"wrapT", wrap}}});
  f.j["textures"].push_back({{"source", f.j["images"].size() - 1}, {"sampler", 0}});
}

int addMaterial(test::GltfFile& f, Json material) {
  f.j["materials"].push_back(std::move(material));
  return int(f.j["materials"].size() - 1);
}

Json checkerMask() {
  return {{"alphaMode", "MASK"},
          {"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorTexture", {{"index", 0}}}}}};
}

/// Floor vertex v's sky fraction from its direct transfer: t_00 = π y_00 · (unoccluded cosine share).
double openFraction(const bake::SurfaceTransfer& t, size_t mesh, size_t v, int bands) {
  return t.perMesh[mesh][v * size_t(bands * bands)].r / (prt::kPi * 0.28209479177387814);
}

bake::BakeSettings directOnly(int samples) {
  bake::BakeSettings s;
  s.bands = 2;
  s.samples = samples;
  s.bounces = 0;
  return s;
}

// ---- Loading

TEST(SceneMaterial, AlphaModesCutoffAndTransmissionAreRead) {
  test::TempDir dir;
  test::GltfFile f;
  addTexture(f, 255, 255, 0);
  // Texture 1 holds the transmission in its R channel: 128 must read 128/255, not sRGB-decoded.
  f.j["images"].push_back(f.j["images"][0]);
  const std::string png = test::encodePng(1, 1, {128, 7, 7, 255});
  f.j["images"][1]["uri"] = "data:image/png;base64," + test::base64(png);
  f.j["textures"].push_back({{"source", 1}});
  Json mask = checkerMask();
  mask["alphaCutoff"] = 0.3;
  addMaterial(f, mask);
  addMaterial(f, {{"alphaMode", "BLEND"},
                  {"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {1, 1, 1, 0.25}}}}});
  addMaterial(
      f, {{"extensions",
           {{"KHR_materials_transmission", {{"transmissionFactor", 0.5}, {"transmissionTexture", {{"index", 1}}}}}}}});
  f.j["extensionsUsed"] = Json::array({"KHR_materials_transmission"});
  f.j["extensionsRequired"] = Json::array({"KHR_materials_transmission"});
  for (int m = 0; m < 3; ++m) addOccluder(f, m);
  const Scene s = loadScene(f.write("materials", dir.path()));
  ASSERT_EQ(s.materials.size(), 3u);
  EXPECT_EQ(s.materials[0].alphaMode, Material::AlphaMode::Mask);
  EXPECT_FLOAT_EQ(s.materials[0].alphaCutoff, 0.3f);
  EXPECT_EQ(s.materials[1].alphaMode, Material::AlphaMode::Blend);
  EXPECT_FLOAT_EQ(s.materials[1].alphaCutoff, 0.5f);  // the default
  EXPECT_EQ(s.materials[2].alphaMode, Material::AlphaMode::Opaque);
  EXPECT_FLOAT_EQ(s.materials[2].transmissionFactor, 0.5f);
  ASSERT_GE(s.materials[2].transmissionTexture, 0);
  EXPECT_FLOAT_EQ(s.textures[size_t(s.materials[2].transmissionTexture)].texels[0].r, 128.0f / 255.0f);
  ASSERT_EQ(s.meshes.size(), 3u);
  for (const MeshInstance& m : s.meshes) EXPECT_TRUE(mayPassLight(s, m));
  // Triangle 0 is (−a,−a), (a,−a), (a,a): barycentrics (b1, b2) put the point at
  // x = −a + 2a(b1 + b2), z = −a + 2a b2. Cell (0, 0) is solid, cell (1, 0) is cut out.
  const float cell = kCell / (2.0f * kHalf);
  EXPECT_EQ(opacityAt(s, s.meshes[0], 0, 0.1f * cell, 0.4f * cell), 1.0f);
  EXPECT_EQ(opacityAt(s, s.meshes[0], 0, 1.0f * cell, 0.5f * cell), 0.0f);
  EXPECT_FLOAT_EQ(alphaAt(s, s.meshes[1], 0, 0.3f, 0.3f), 0.25f);
  EXPECT_FLOAT_EQ(opacityAt(s, s.meshes[1], 0, 0.3f, 0.3f), 0.25f);
  EXPECT_NEAR(opacityAt(s, s.meshes[2], 0, 0.3f, 0.3f), 1.0f - 0.5f * 128.0f / 255.0f, 1e-6f);
  // The baked file keeps the materials: prt render reads the same cutouts and panes.
  Scene withTransfer = s;
  withTransfer.transferBands = 1;
  for (MeshInstance& m : withTransfer.meshes) m.transfer.assign(m.vertexCount(), glm::vec3(1.0f));
  const std::string baked = dir.file("materials.glb");
  writeBakedScene(s.path, withTransfer, nullptr, baked);
  const Scene back = loadScene(baked);
  ASSERT_EQ(back.materials.size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(back.materials[k].alphaMode, s.materials[k].alphaMode);
    EXPECT_EQ(back.materials[k].alphaCutoff, s.materials[k].alphaCutoff);
    EXPECT_EQ(back.materials[k].transmissionFactor, s.materials[k].transmissionFactor);
    EXPECT_EQ(opacityAt(back, back.meshes[k], 0, 0.3f, 0.3f), opacityAt(s, s.meshes[k], 0, 0.3f, 0.3f));
  }
}

TEST(SceneMaterial, OpaqueIgnoresAlphaAndBadAlphaModeIsRefused) {
  test::TempDir dir;
  test::GltfFile f;
  addMaterial(f, {{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {1, 1, 1, 0.0}}}}});
  addOccluder(f, 0);
  const Scene s = loadScene(f.write("opaque", dir.path()));
  EXPECT_FALSE(mayPassLight(s, s.meshes[0]));
  EXPECT_EQ(opacityAt(s, s.meshes[0], 0, 0.3f, 0.3f), 1.0f);
  f.j["materials"][0]["alphaMode"] = "CUTOUT";
  try {
    loadScene(f.write("badmode", dir.path()));
    FAIL() << "alphaMode CUTOUT accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("material 0: alphaMode 'CUTOUT'"), std::string::npos) << e.what();
  }
}

// ---- Cutouts in the surface bake and the probe bake

// A uniform sky over the floor, seen through the checker: the open fraction at floor vertex p
// is 1 − Σ_{solid cells} F(p → cell), F the exact view factor of each cell. The bake's
// estimate is (1/N) Σ V over N cosine-weighted rays: binomial, standard deviation at most
// 0.5/√N = 0.0055 for N = 8192 (the Sobol net does better); 0.025 a vertex is 4.5σ, and the
// mean error over the 25 vertices, σ ≤ 0.0011, must stay under 0.006. Without cutouts the
// square is solid: 1 − F ≈ 0.1 instead of ≈ 0.55.
TEST(BakeCutout, CheckerMaskLetsThroughItsOpenFraction) {
  test::TempDir dir;
  test::GltfFile f;
  addTexture(f, 255, 255, 0);
  addOccluder(f, addMaterial(f, checkerMask()));
  addFloor(f);
  const Scene s = loadScene(f.write("checker", dir.path()));
  ASSERT_EQ(s.meshes.size(), 2u);
  const bake::SurfaceTransfer t = bake::bakeSurface(s, directOnly(8192));
  const MeshInstance& floor = s.meshes[1];
  double meanError = 0.0, maxError = 0.0;
  for (size_t v = 0; v < floor.vertexCount(); ++v) {
    const glm::vec3 p = floor.positions[v];
    const double solid = overCells(cornerViewFactor, p.x, p.z, kHeight, false);
    const double whole = overCells(cornerViewFactor, p.x, p.z, kHeight, true);
    ASSERT_GT(whole, 0.85);  // the test means something: the square hides most of the sky
    const double want = 1.0 - solid, got = openFraction(t, 1, v, 2);
    EXPECT_NEAR(got, want, 0.025) << "vertex " << v << " at " << p.x << "," << p.z;
    meanError += (got - want) / double(floor.vertexCount());
    maxError = std::max(maxError, std::abs(got - want));
    if (v == 12)
      std::printf("centre vertex: open fraction %.4f, closed form %.4f (solid square: %.4f)\n", got, want, 1.0 - whole);
  }
  std::printf("max error %.4f, mean error %.5f over %zu vertices\n", maxError, meanError, floor.vertexCount());
  EXPECT_LT(std::abs(meanError), 0.006);
}

// A probe 0.5 below the checker, nothing else in the scene: M_00 is the share of the sphere
// the sky fills, 1 − Σ_{solid cells} Ω(cell)/4π. 16384 uniform sphere rays: σ ≤ 0.004; 0.015
// is under 4σ. A solid square would give 1 − Ω/4π ≈ 0.54 instead of ≈ 0.77.
TEST(BakeCutout, ProbeSeesTheSkyThroughTheChecker) {
  test::TempDir dir;
  test::GltfFile f;
  addTexture(f, 255, 255, 0);
  addOccluder(f, addMaterial(f, checkerMask()));
  const Scene s = loadScene(f.write("checker_probe", dir.path()));
  bake::ProbeSettings ps;
  ps.bands = 2;
  ps.samples = 16384;
  ps.dims = glm::ivec3(1);
  const glm::dvec3 at(0.3, kHeight - 0.5, -0.2);
  ps.boundsMin = at - 0.05;
  ps.boundsMax = at + 0.05;
  const ProbeGrid g = bake::bakeProbes(s, {}, ps);
  ASSERT_EQ(g.probeCount(), 1u);
  EXPECT_EQ(g.validity[0], 1.0f);
  const double want = 1.0 - overCells(cornerSolidAngle, at.x, at.z, 0.5, false) / (4.0 * prt::kPi);
  ASSERT_LT(1.0 - overCells(cornerSolidAngle, at.x, at.z, 0.5, true) / (4.0 * prt::kPi), want - 0.15);
  std::printf("probe M_00 %.4f, closed form %.4f\n", g.transfer[0], want);
  EXPECT_NEAR(g.transfer[0], want, 0.015);
}

// ---- Partial occluders: transmission, BLEND, and both

struct PaneCase {
  const char* name;
  Json material;
  double opacity;  // alpha × (1 − transmission)
};

void PrintTo(const PaneCase& c, std::ostream* os) { *os << c.name; }

class BakePartialOccluder : public ::testing::TestWithParam<PaneCase> {};

// The square as a pane of opacity α over the floor: the sky behind it comes through 1 − α, so
// the open fraction is 1 − α F. The coin that decides each ray adds binomial noise of the same
// size as the visibility's: the tolerances of BakeCutout hold.
TEST_P(BakePartialOccluder, LetsThroughOneMinusItsOpacity) {
  test::TempDir dir;
  test::GltfFile f;
  addOccluder(f, addMaterial(f, GetParam().material));
  addFloor(f);
  f.j["extensionsUsed"] = Json::array({"KHR_materials_transmission"});
  const Scene s = loadScene(f.write(GetParam().name, dir.path()));
  const bake::SurfaceTransfer t = bake::bakeSurface(s, directOnly(8192));
  const MeshInstance& floor = s.meshes[1];
  double meanError = 0.0, maxError = 0.0;
  for (size_t v = 0; v < floor.vertexCount(); ++v) {
    const glm::vec3 p = floor.positions[v];
    const double want = 1.0 - GetParam().opacity * overCells(cornerViewFactor, p.x, p.z, kHeight, true);
    const double got = openFraction(t, 1, v, 2);
    EXPECT_NEAR(got, want, 0.025) << "vertex " << v;
    meanError += (got - want) / double(floor.vertexCount());
    maxError = std::max(maxError, std::abs(got - want));
  }
  std::printf("opacity %.2f: max error %.4f, mean error %.5f\n", GetParam().opacity, maxError, meanError);
  EXPECT_LT(std::abs(meanError), 0.006);
}

INSTANTIATE_TEST_SUITE_P(
    Panes, BakePartialOccluder,
    ::testing::Values(
        PaneCase{
            "transmission", {{"extensions", {{"KHR_materials_transmission", {{"transmissionFactor", 0.5}}}}}}, 0.5},
        PaneCase{"blend",
                 {{"alphaMode", "BLEND"},
                  {"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {1, 1, 1, 0.5}}}}},
                 0.5},
        PaneCase{"both",
                 {{"alphaMode", "BLEND"},
                  {"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {0.2, 0.9, 0.4, 0.5}}}},
                  {"extensions", {{"KHR_materials_transmission", {{"transmissionFactor", 0.5}}}}}},
                 0.25}),
    [](const ::testing::TestParamInfo<PaneCase>& c) { return std::string(c.param.name); });

// The bounces gather over accepted hits as over any hit: under a white pane of opacity α
// facing down (over a black floor, so nothing else reflects), the floor's first bounce is
// (1/N) Σ ρ t⁰ over the rays the pane stopped, α of what the opaque pane gives (whose own
// transfer t⁰ is the same bits in both bakes: the pane does not occlude itself). The coin
// thins about 3700 hits a vertex to half: a relative deviation of √((1 − α)/(α·3700)) = 1.6%,
// so σ ≈ 0.008 on the ratio; 0.03 (6%) a vertex is under 4σ (measured worst of 25: 0.018).
// Ignoring the pane's hits would give 0, keeping all of them 1.
TEST(BakePartialOccluderBounce, FloorGathersOpacityTimesTheOpaqueBounce) {
  test::TempDir dir;
  auto bounce = [&](const Json& pane) {
    test::GltfFile f;
    addOccluder(f, addMaterial(f, pane));
    addFloor(f, addMaterial(
                    f, {{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {0.0, 0.0, 0.0, 1.0}}}}}));
    bake::BakeSettings bs = directOnly(4096);
    bs.bounces = 1;
    bs.keepLowerOrder = true;
    const bake::SurfaceTransfer t = bake::bakeSurface(loadScene(f.write("bounce", dir.path())), bs);
    std::vector<double> out;  // the floor's bounce-1 DC per vertex
    for (size_t v = 0; v < t.perMesh[1].size() / 4; ++v)
      out.push_back(t.perMesh[1][4 * v].r - t.perMeshLowerOrder[1][4 * v].r);
    return out;
  };
  const std::vector<double> opaque =
      bounce({{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {1.0, 1.0, 1.0, 1.0}}}}});
  const std::vector<double> half =
      bounce({{"alphaMode", "BLEND"},
              {"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {1.0, 1.0, 1.0, 0.5}}}}});
  ASSERT_EQ(opaque.size(), half.size());
  double worst = 0.0;
  for (size_t v = 0; v < opaque.size(); ++v) {
    ASSERT_GT(opaque[v], 0.05);  // the pane's underside sees the sky past the floor: it reflects
    EXPECT_NEAR(half[v] / opaque[v], 0.5, 0.03) << "vertex " << v;
    worst = std::max(worst, std::abs(half[v] / opaque[v] - 0.5));
  }
  std::printf("bounce under an α = 0.5 pane / under the opaque pane: 0.5 ± %.4f\n", worst);
}

// Bounces use the bounce albedo (docs/bake.md, "Materials"): under a white pane of metallic m
// and roughness 1 over a black floor, the floor's first bounce is (1 − m) + m (Ā + B̄) times
// the dielectric pane's, (Ā, B̄) = brdf::cosineAveragedDfg(1). The rays, hits and the pane's
// own t⁰ are the same bits in every bake (albedo does not change visibility), so the ratio is
// exact up to float rounding in the sums: 1e-5. A metal pane (metallic 1, or its texture's B
// channel at 255) sends its lobe's Ā + B̄, the white metal's hemispherical albedo.
TEST(BakeAlbedoBounce, FloorGathersTheMetalPanesLobeAsADiffuseBounce) {
  test::TempDir dir;
  auto bounce = [&](Json pbr, bool texture = false) {
    test::GltfFile f;
    if (texture) {
      f.j["images"].push_back(
          {{"uri", "data:image/png;base64," + test::base64(test::encodePng(1, 1, {0, 255, 255, 255}))}});
      f.j["textures"].push_back({{"source", 0}});
      pbr["metallicRoughnessTexture"] = {{"index", 0}};
    }
    pbr["baseColorFactor"] = {1.0, 1.0, 1.0, 1.0};
    addOccluder(f, addMaterial(f, {{"pbrMetallicRoughness", pbr}}));
    addFloor(f,
             addMaterial(f, {{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {0, 0, 0, 1.0}}}}}));
    bake::BakeSettings bs = directOnly(1024);
    bs.bounces = 1;
    bs.keepLowerOrder = true;
    const bake::SurfaceTransfer t = bake::bakeSurface(loadScene(f.write("metal", dir.path())), bs);
    std::vector<double> out;  // the floor's bounce-1 DC per vertex
    for (size_t v = 0; v < t.perMesh[1].size() / 4; ++v)
      out.push_back(t.perMesh[1][4 * v].r - t.perMeshLowerOrder[1][4 * v].r);
    return out;
  };
  const std::vector<double> dielectric = bounce({{"metallicFactor", 0.0}});
  const std::vector<double> quarter = bounce({{"metallicFactor", 0.75}});
  const std::vector<double> metal = bounce(Json::object());  // metallicFactor absent: 1
  const std::vector<double> textured = bounce({{"metallicFactor", 1.0}}, true);
  const glm::dvec2 ab = brdf::cosineAveragedDfg(1.0);
  const double white = double(float(ab.x) + float(ab.y));
  ASSERT_GT(white, 0.3);  // 0.41: single scattering loses much at roughness 1
  ASSERT_LT(white, 1.0);
  for (size_t v = 0; v < dielectric.size(); ++v) {
    ASSERT_GT(dielectric[v], 0.05);
    EXPECT_NEAR(quarter[v] / dielectric[v], 0.25 + 0.75 * white, 1e-5) << "vertex " << v;
    EXPECT_NEAR(metal[v] / dielectric[v], white, 1e-5) << "vertex " << v;
    EXPECT_NEAR(textured[v] / dielectric[v], white, 1e-5) << "vertex " << v;
  }
}

// ---- Determinism and opaque scenes

bool sameBits(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(glm::vec3)) == 0;
}

// A floor of albedo 0.7 under the checker and, lower, a half-transparent pane: bounces gather
// over hits on both. Surface and probes have the same bits for 1 and 2 threads; another seed
// differs.
TEST(BakeCutout, SameBitsForAnyThreadCount) {
  test::TempDir dir;
  test::GltfFile f;
  addTexture(f, 200, 255, 0);
  addOccluder(f, addMaterial(f, checkerMask()));
  addOccluder(
      f,
      addMaterial(f, {{"alphaMode", "BLEND"},
                      {"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {0.5, 0.5, 0.5, 0.5}}}}}),
      0.5f * kHeight);
  addFloor(f, addMaterial(
                  f, {{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {0.7, 0.7, 0.7, 1.0}}}}}));
  const Scene s = loadScene(f.write("threads", dir.path()));
  bake::BakeSettings bs;
  bs.samples = 256;
  bs.bounces = 2;
  bs.keepLowerOrder = true;
  bake::ProbeSettings ps;
  ps.samples = 256;
  ps.dims = glm::ivec3(3, 2, 3);
  ps.boundsMin = glm::dvec3(-1.0, 0.1, -1.0);
  ps.boundsMax = glm::dvec3(1.0, 0.9, 1.0);
  auto bake = [&](int threads, uint64_t seed, bake::SurfaceTransfer& t, ProbeGrid& g) {
    bs.threads = ps.threads = threads;
    bs.seed = ps.seed = seed;
    t = bake::bakeSurface(s, bs);
    g = bake::bakeProbes(s, t.perMeshLowerOrder, ps);
  };
  bake::SurfaceTransfer t1, t2, t3;
  ProbeGrid g1, g2, g3;
  bake(1, 5, t1, g1);
  bake(2, 5, t2, g2);
  bake(2, 6, t3, g3);
  for (size_t k = 0; k < s.meshes.size(); ++k) {
    EXPECT_TRUE(sameBits(t1.perMesh[k], t2.perMesh[k])) << "instance " << k;
    EXPECT_FALSE(sameBits(t1.perMesh[k], t3.perMesh[k])) << "instance " << k;
  }
  ASSERT_EQ(g1.transfer.size(), g2.transfer.size());
  EXPECT_EQ(0, std::memcmp(g1.transfer.data(), g2.transfer.data(), g1.transfer.size() * sizeof(float)));
  EXPECT_NE(0, std::memcmp(g1.transfer.data(), g3.transfer.data(), g1.transfer.size() * sizeof(float)));
}

// Alpha that cannot cut anything changes nothing: an OPAQUE square whose factor and texture
// alpha are 0 (OPAQUE ignores alpha), a MASK square whose alpha is 1 (traced without a filter:
// passesLight), and a MASK square whose texture has a clear texel that its coordinates never
// reach (traced through the filter, which then accepts every hit) bake to the bits of the
// plain opaque square, bounces included.
TEST(BakeCutout, AlphaThatCutsNothingChangesNoBit) {
  test::TempDir dir;
  enum Texture { kNone, kClear, kUnreached };
  auto bakeWith = [&](const Json& material, Texture texture) {
    test::GltfFile f;
    // Unreached: texel (0, 0) solid, the others clear, clamped, read only at u, v ∈ [0, ¼],
    // where the bilinear lookup is texel (0, 0) alone.
    if (texture != kNone) addTexture(f, 255, texture == kClear ? 0 : 255, 0, texture == kUnreached);
    addOccluder(f, addMaterial(f, material), kHeight, texture == kUnreached ? 0.125f / kHalf : 0.5f / kCell);
    addFloor(f, addMaterial(
                    f, {{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {0.7, 0.7, 0.7, 1.0}}}}}));
    bake::BakeSettings bs;
    bs.samples = 256;
    bs.bounces = 2;
    const Scene s = loadScene(f.write("nocut", dir.path()));
    EXPECT_EQ(passesLight(s)[0], texture == kUnreached) << material.dump();
    return bake::bakeSurface(s, bs);
  };
  const Json grey = {{"metallicFactor", 0}, {"baseColorFactor", {0.6, 0.6, 0.6, 1.0}}};
  const Json greyTextured = {
      {"metallicFactor", 0}, {"baseColorFactor", {0.6, 0.6, 0.6, 1.0}}, {"baseColorTexture", {{"index", 0}}}};
  const bake::SurfaceTransfer plain = bakeWith({{"pbrMetallicRoughness", grey}}, kNone);
  Json clear = {
      {"pbrMetallicRoughness",
       {{"metallicFactor", 0}, {"baseColorFactor", {0.6, 0.6, 0.6, 0.0}}, {"baseColorTexture", {{"index", 0}}}}}};
  const bake::SurfaceTransfer opaque = bakeWith(clear, kClear);
  const bake::SurfaceTransfer solidMask =
      bakeWith({{"alphaMode", "MASK"}, {"alphaCutoff", 0.9}, {"pbrMetallicRoughness", grey}}, kNone);
  const bake::SurfaceTransfer unreached =
      bakeWith({{"alphaMode", "MASK"}, {"pbrMetallicRoughness", greyTextured}}, kUnreached);
  for (size_t k = 0; k < 2; ++k) {
    EXPECT_TRUE(sameBits(plain.perMesh[k], opaque.perMesh[k])) << "instance " << k;
    EXPECT_TRUE(sameBits(plain.perMesh[k], solidMask.perMesh[k])) << "instance " << k;
    EXPECT_TRUE(sameBits(plain.perMesh[k], unreached.perMesh[k])) << "instance " << k;
  }
}

// passesLight: which instances the bake tests hits on.
TEST(SceneMaterial, PassesLightOnlyWhereAlphaCanCut) {
  test::TempDir dir;
  test::GltfFile f;
  addTexture(f, 255, 255, 0);
  f.j["images"].push_back(f.j["images"][0]);  // image 1: alpha 1 everywhere (a JPEG's)
  const std::string png = test::encodePng(1, 1, {9, 9, 9, 255});
  f.j["images"][1]["uri"] = "data:image/png;base64," + test::base64(png);
  f.j["textures"].push_back({{"source", 1}});
  const Json solidTexture = {{"metallicFactor", 0}, {"baseColorTexture", {{"index", 1}}}};
  const std::vector<std::pair<Json, bool>> cases = {
      {checkerMask(), true},
      {{{"alphaMode", "MASK"}, {"pbrMetallicRoughness", solidTexture}}, false},
      {{{"alphaMode", "MASK"},
        {"alphaCutoff", 0.6},
        {"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {1, 1, 1, 0.5}}}}},
       true},
      {{{"alphaMode", "BLEND"}, {"pbrMetallicRoughness", solidTexture}}, false},
      {{{"alphaMode", "BLEND"},
        {"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {1, 1, 1, 0.99}}}}},
       true},
      {{{"extensions", {{"KHR_materials_transmission", {{"transmissionFactor", 0.1}}}}}}, true},
      {{{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"baseColorFactor", {1, 1, 1, 0.0}}}}}, false}};
  for (const auto& [material, passes] : cases) addOccluder(f, addMaterial(f, material));
  const Scene s = loadScene(f.write("passes", dir.path()));
  const std::vector<char> got = passesLight(s);
  ASSERT_EQ(got.size(), cases.size());
  for (size_t k = 0; k < cases.size(); ++k) EXPECT_EQ(bool(got[k]), cases[k].second) << cases[k].first.dump();
}

// The probe bake traces packets of 8 (RayScene::intersect8): every ray must get the hit it gets
// traced alone (RayScene::intersect of one ray), bit for bit, through a cutout (the checker
// mask) and a partial occluder (BLEND, opacity 0.5: the per-ray coin in the filter, which
// Embree calls with 8 lanes for a packet and with one for a lone ray; a coin that read another
// lane's ray would differ here). Rays from points under and above the
// occluder, in every direction.
TEST(BakeCutout, PacketsOfEightFindTheHitsOfSingleRays) {
  test::TempDir dir;
  for (const bool blend : {false, true}) {
    SCOPED_TRACE(blend ? "blend" : "mask");
    test::GltfFile f;
    addTexture(f, 255, 255, 0);
    addOccluder(f, addMaterial(f, blend ? Json{{"alphaMode", "BLEND"},
                                               {"pbrMetallicRoughness",
                                                {{"metallicFactor", 0}, {"baseColorFactor", {1, 1, 1, 0.5}}}}}
                                        : checkerMask()));
    addFloor(f);
    const Scene s = loadScene(f.write(blend ? "blend" : "mask", dir.path()));
    const bake::RayScene rays(s);
    uint64_t state = 12345;
    auto uniform = [&] { return float(double(bake::splitMix64(state++) >> 11) * 0x1.0p-53); };
    constexpr size_t kRays = 1000;  // 125 packets; the sets below end in partial packets
    std::vector<bake::Ray> single(kRays);
    std::vector<bake::RayPacket8> packets((kRays + 7) / 8);
    size_t hits = 0, partial = 0;
    for (size_t i = 0; i < kRays; ++i) {
      const glm::vec3 o(2.0f * uniform() - 1.0f, i % 2 ? 0.25f : kHeight + 0.25f, 2.0f * uniform() - 1.0f);
      const float z = 2.0f * uniform() - 1.0f, phi = 2.0f * float(prt::kPi) * uniform();
      const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
      const glm::vec3 d(r * std::cos(phi), z, r * std::sin(phi));
      single[i].start(o, d, 0.0f, std::numeric_limits<float>::infinity());
      packets[i / 8].start(int(i % 8), o, d, 0.0f, std::numeric_limits<float>::infinity());
    }
    // Sets start at whole packets; three of the four end in a partial one, whose other lanes
    // are not traced.
    std::vector<char> traced(kRays, 0);
    for (const auto& [first, n] : {std::pair<size_t, size_t>{0, 245}, {248, 248}, {496, 241}, {744, 251}}) {
      for (size_t i = first; i < first + n; ++i) rays.intersect(&single[i], 1);  // one ray at a time
      rays.intersect8(packets.data() + first / 8, n);
      std::fill_n(traced.begin() + std::ptrdiff_t(first), n, 1);
      partial += n % 8 != 0;
    }
    for (size_t i = 0; i < kRays; ++i) {
      if (!traced[i]) continue;
      const bake::Ray& a = single[i];
      const bake::RayPacket8& p = packets[i / 8];
      const int l = int(i % 8);
      hits += a.hit() && a.mesh == 0;
      ASSERT_EQ(a.mesh, p.mesh[l]) << "ray " << i;
      ASSERT_EQ(a.tri, p.tri[l]) << "ray " << i;
      ASSERT_EQ(std::memcmp(&a.tfar, &p.tfar[l], 4), 0) << "ray " << i;
      ASSERT_EQ(std::memcmp(&a.u, &p.u[l], 4), 0) << "ray " << i;
      ASSERT_EQ(std::memcmp(&a.v, &p.v[l], 4), 0) << "ray " << i;
      ASSERT_EQ(a.backface(), p.backface(l)) << "ray " << i;
    }
    EXPECT_GT(hits, 100u);  // the occluder is hit (and passed) often enough to mean something
    EXPECT_EQ(partial, 3u);
  }
}

}  // namespace
}  // namespace prt
