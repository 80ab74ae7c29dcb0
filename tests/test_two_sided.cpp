// Double-sided materials in the bake (surface_bake.cpp, probe_bake.cpp) and the baked file
// (gltf_write.cpp, gltf_read.cpp): both sides of a vertex receive light and reflect it, and a
// ray that hits the back of a double-sided face gathers that side's light. Checked against
// closed forms (an unoccluded side's transfer, the irradiance of each hemisphere, form factors
// integrated numerically in the test), against the one-sided bake, and across thread counts.
#include <cmath>
#include <cstring>
#include <filesystem>

#include <gtest/gtest.h>

#include "gltf_file.h"
#include "harness.h"
#include "prt/bake/memory_estimate.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/surface_bake.h"
#include "prt/math.h"
#include "prt/probe_grid.h"
#include "prt/relight.h"
#include "prt/sh.h"
#include "test_scenes.h"

namespace prt {
namespace {

constexpr double kY00 = 0.28209479177387814;  // y_00 = 1 / (2√π)

// The SH projection of a sky of radiance `up` above the horizon (y > 0) and `down` below, by a
// midpoint rule in (y, φ): uniform in y is uniform in solid angle, and the horizon is a cell
// boundary, so the step is integrated without error beyond the rule's own.
sh::ShRgb stepSky(int bands, double up, double down) {
  const int n2 = bands * bands, ny = 400, nphi = 400;
  std::vector<double> c(size_t(n2), 0.0);
  float y[sh::kMaxBands * sh::kMaxBands];
  const double dOmega = (2.0 / ny) * (2.0 * prt::kPi / nphi);
  for (int i = 0; i < ny; ++i) {
    const double cy = -1.0 + (i + 0.5) * 2.0 / ny, r = std::sqrt(1.0 - cy * cy);
    for (int k = 0; k < nphi; ++k) {
      const double phi = (k + 0.5) * 2.0 * prt::kPi / nphi;
      sh::evaluate(bands, glm::vec3(float(r * std::cos(phi)), float(cy), float(r * std::sin(phi))), y);
      const double L = cy > 0.0 ? up : down;
      for (int j = 0; j < n2; ++j) c[size_t(j)] += L * y[j] * dOmega;
    }
  }
  sh::ShRgb l(bands);
  for (int j = 0; j < n2; ++j) l.c[size_t(j)] = glm::vec3(float(c[size_t(j)]));
  return l;
}

// The form factor from a point to a parallel square of half-size a at distance h, centred
// above it: F = (1/π) ∫∫ h² / (x² + z² + h²)² dx dz, by a midpoint rule.
double squareFormFactor(double a, double h) {
  const int n = 2000;
  const double d = 2.0 * a / n;
  double sum = 0.0;
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < n; ++k) {
      const double x = -a + (i + 0.5) * d, z = -a + (k + 0.5) * d, q = x * x + z * z + h * h;
      sum += h * h / (q * q);
    }
  return sum * d * d / prt::kPi;
}

// The solid angle of that square: 4 atan(a² / (h √(2a² + h²))).
double squareSolidAngle(double a, double h) { return 4.0 * std::atan(a * a / (h * std::sqrt(2.0 * a * a + h * h))); }

// Materials: 0 single-sided, 1 double-sided, both of albedo rho.
Scene twoMaterialScene(std::vector<MeshInstance> meshes, float rho, const std::vector<int>& material) {
  Scene s = test::makeScene(std::move(meshes), rho);
  Material two = s.materials[0];
  two.doubleSided = true;
  s.materials.push_back(two);
  for (size_t k = 0; k < s.meshes.size(); ++k) s.meshes[k].material = material[k];
  return s;
}

// The closed form of an unoccluded side with normal n: Â_l y_lm(n).
void expectUnoccluded(const glm::vec3* t, const glm::vec3& n, int bands, float tol, const char* what) {
  float y[sh::kMaxBands * sh::kMaxBands];
  sh::evaluate(bands, n, y);
  for (int i = 0; i < bands * bands; ++i)
    EXPECT_NEAR(t[i].g, float(sh::clampedCosineFactor(sh::bandOf(i))) * y[i], tol) << what << " coefficient " << i;
}

bool sameBits(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(glm::vec3)) == 0;
}

TEST(BakeTwoSided, IsolatedPlaneBothSidesMatchTheClosedForm) {
  // Nothing occludes either side of a lone plane: the front is Â_l y(+Y), the back Â_l y(−Y),
  // shadowed (rays) and unshadowed (closed form) alike. Under a sky of radiance `up` above and
  // `down` below, each side's irradiance is its hemisphere's: π up in front, π down behind (the
  // band-limited step gives exactly that at the poles, for any band count).
  Scene s = twoMaterialScene({test::makePlane(glm::vec3(0.0f), 2.0f, 4)}, 0.8f, {1});
  const size_t V = s.meshes[0].vertexCount();
  const sh::ShRgb sky = stepSky(3, 1.0, 0.25);
  for (bool shadowed : {true, false}) {
    SCOPED_TRACE(shadowed ? "shadowed" : "unshadowed");
    bake::BakeSettings bs;
    bs.samples = 1024;
    bs.bounces = 1;
    bs.shadowed = shadowed;
    const bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
    ASSERT_EQ(t.perMesh[0].size(), 2 * V * 9);
    EXPECT_EQ(t.stats.vertices, V);
    EXPECT_EQ(t.stats.backVertices, V);
    for (size_t v = 0; v < V; ++v) {
      const glm::vec3* front = &t.perMesh[0][v * 9];
      const glm::vec3* back = &t.perMesh[0][(V + v) * 9];
      expectUnoccluded(front, {0, 1, 0}, 3, 1e-2f, "front");
      expectUnoccluded(back, {0, -1, 0}, 3, 1e-2f, "back");
      EXPECT_NEAR(back[0].g, prt::kPi * kY00, 1e-5);  // uniform sky L: E = π L
      EXPECT_NEAR(sh::dot(front, sky.c.data(), 9).g, prt::kPi * 1.0, 1e-2);
      EXPECT_NEAR(sh::dot(back, sky.c.data(), 9).g, prt::kPi * 0.25, 1e-2);
    }
  }
}

// A small one-sided plane A (half-size 0.05, facing up) under a big plane B (half-size 2, at
// height 1, facing up, albedo rho), uniform sky of radiance 1. A sees the sky around B and B's
// underside, its back. With B double-sided, the back is lit by the sky below (E = π, A's shadow
// on it < 0.3%) and sends ρ/π · π: A's irradiance with one bounce is π(1 − F) + ρ π F, F the
// form factor of B from A. With B one-sided its back blocks and sends nothing: π(1 − F).
struct UnderRoof {
  static constexpr float kRho = 0.6f;
  Scene scene;
  size_t centre = 4;  // A's middle vertex (3×3 vertices)
  explicit UnderRoof(bool twoSidedRoof) {
    scene = twoMaterialScene({test::makePlane(glm::vec3(0.0f), 0.1f, 2), test::makePlane(glm::vec3(0, 1, 0), 4.0f, 2)},
                             kRho, {0, twoSidedRoof ? 1 : 0});
  }
};

TEST(BakeTwoSided, RayHittingTheBackOfADoubleSidedFaceGathersItsLight) {
  const double F = squareFormFactor(2.0, 1.0);
  bake::BakeSettings bs;
  bs.samples = 4096;
  bs.bounces = 1;
  for (bool two : {false, true}) {
    SCOPED_TRACE(two ? "double-sided roof" : "one-sided roof");
    const UnderRoof r(two);
    const bake::SurfaceTransfer t = bake::bakeSurface(r.scene, bs);
    ASSERT_EQ(t.perMesh[0].size(), 9u * 9);  // A is one-sided: front only
    // E = t_00 · l_00 with l_00 = 4π y_00 for a sky of radiance 1.
    const double e = t.perMesh[0][r.centre * 9].g * 4.0 * prt::kPi * kY00;
    const double expected = two ? prt::kPi * (1.0 - F) + UnderRoof::kRho * prt::kPi * F : prt::kPi * (1.0 - F);
    std::printf("[ measured ] %s roof: E %.5f, closed form %.5f (F %.5f)\n", two ? "double-sided" : "one-sided", e,
                expected, F);
    EXPECT_NEAR(e, expected, 0.01 * expected);
  }
}

TEST(BakeTwoSided, RealVerticesKeepTheirRaysAndDirectTransfer) {
  // The back sides are numbered after every real vertex with streams of their own, so the
  // direct pass of the real vertices casts the one-sided bake's rays: bounces 0 gives the very
  // same front transfer bits whether B is double-sided or not. The surfaceBakeRays of a real
  // vertex are the same too, and a back side's rays leave into the other hemisphere.
  bake::BakeSettings bs;
  bs.samples = 256;
  bs.bounces = 0;
  const UnderRoof one(false), two(true);
  const bake::SurfaceTransfer a = bake::bakeSurface(one.scene, bs), b = bake::bakeSurface(two.scene, bs);
  const size_t VB = two.scene.meshes[1].vertexCount();
  EXPECT_TRUE(sameBits(a.perMesh[0], b.perMesh[0]));
  ASSERT_EQ(b.perMesh[1].size(), 2 * a.perMesh[1].size());
  EXPECT_TRUE(sameBits(a.perMesh[1], std::vector<glm::vec3>(b.perMesh[1].begin(), b.perMesh[1].begin() + VB * 9)));
  const size_t realVertices = one.scene.meshes[0].vertexCount() + VB;
  const bake::RayScene oneRays(one.scene), twoRays(two.scene);
  const std::vector<bake::Ray> ra = bake::surfaceBakeRays(one.scene, bs, oneRays, {0, realVertices - 1});
  const std::vector<bake::Ray> rb = bake::surfaceBakeRays(two.scene, bs, twoRays, {0, realVertices - 1, realVertices});
  for (size_t j = 0; j < ra.size(); ++j) EXPECT_EQ(0, std::memcmp(&ra[j].dir, &rb[j].dir, sizeof(glm::vec3)));
  for (size_t j = 2 * size_t(bs.samples); j < rb.size(); ++j) EXPECT_LT(rb[j].dir.y, 0.0f);  // B's first back side
}

TEST(BakeTwoSided, SameBitsForAnyThreadCount) {
  const UnderRoof r(true);
  bake::BakeSettings bs;
  bs.samples = 512;
  bs.bounces = 2;
  bs.keepLowerOrder = true;
  bs.threads = 1;
  const bake::SurfaceTransfer a = bake::bakeSurface(r.scene, bs);
  bs.threads = 2;
  const bake::SurfaceTransfer b = bake::bakeSurface(r.scene, bs);
  for (size_t k = 0; k < r.scene.meshes.size(); ++k) {
    EXPECT_TRUE(sameBits(a.perMesh[k], b.perMesh[k])) << k;
    EXPECT_TRUE(sameBits(a.perMeshLowerOrder[k], b.perMeshLowerOrder[k])) << k;
  }
  EXPECT_EQ(a.stats.hitRecords, b.stats.hitRecords);
}

TEST(BakeTwoSided, MemoryEstimateCountsTheBackSides) {
  // The roof's back sides are vertices of the bake: one transfer buffer holds A's 9 vertices
  // and both sides of B's 9; the hit records' per-vertex offsets grow alike.
  const UnderRoof one(false), two(true);
  bake::BakeSettings bs;
  const bake::MemoryEstimate a = bake::estimateBakeMemory(one.scene, bs, nullptr, 0.5);
  const bake::MemoryEstimate b = bake::estimateBakeMemory(two.scene, bs, nullptr, 0.5);
  EXPECT_EQ(a.transfer, 18u * 9 * 12);
  EXPECT_EQ(b.transfer, 27u * 9 * 12);
  EXPECT_GT(b.hits, a.hits);
  EXPECT_EQ(a.bvh, b.bvh);  // each triangle once in the BVH
}

TEST(ProbeBakeTwoSided, ProbeSeesTheBackOfADoubleSidedRoof) {
  // One probe 1 below the roof B alone (uniform sky 1, K = 1): rays into B's solid angle Ω
  // hit its back, which a double-sided B lights with ρ/π · (t⁰_back · l) = ρ; the rest see the
  // sky. c_00 = y_00 [(4π − Ω) + ρ Ω]. A one-sided B sends nothing there and its back counts
  // towards the inside test (Ω / 4π ≈ 0.3 > 0.25: the probe is inside geometry).
  const double omega = squareSolidAngle(2.0, 1.0);
  for (bool two : {false, true}) {
    SCOPED_TRACE(two ? "double-sided" : "one-sided");
    Scene s = twoMaterialScene({test::makePlane(glm::vec3(0, 1, 0), 4.0f, 2)}, UnderRoof::kRho, {two ? 1 : 0});
    bake::BakeSettings bs;
    bs.samples = 1024;
    bs.bounces = 1;
    bs.keepLowerOrder = true;
    bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
    bake::ProbeSettings ps;
    ps.dims = glm::ivec3(1);
    ps.boundsMin = glm::dvec3(-0.05);
    ps.boundsMax = glm::dvec3(0.05);
    ps.samples = 8192;
    ps.bounces = 1;
    const ProbeGrid g = bake::bakeProbes(s, t.perMeshLowerOrder, ps);
    if (!two) {  // inside geometry, and with no valid neighbour not even stored
      EXPECT_EQ(g.probeCount(), 0u);
      continue;
    }
    ASSERT_EQ(g.probeCount(), 1u);
    ASSERT_EQ(g.validity[0], 1.0f);
    const std::vector<glm::vec3> c = relightProbes(g, stepSky(3, 1.0, 1.0));
    const double expected = kY00 * ((4.0 * prt::kPi - omega) + UnderRoof::kRho * omega);
    std::printf("[ measured ] probe c00 %.5f, closed form %.5f (Ω %.4f)\n", c[0].g, expected, omega);
    EXPECT_NEAR(c[0].g, expected, 0.01 * expected);
  }
}

TEST(ProbeBakeTwoSided, SameGridForAnyThreadCount) {
  const UnderRoof r(true);
  bake::BakeSettings bs;
  bs.samples = 256;
  bs.bounces = 1;
  bs.keepLowerOrder = true;
  bake::SurfaceTransfer t = bake::bakeSurface(r.scene, bs);
  bake::ProbeSettings ps;
  ps.dims = glm::ivec3(3, 2, 3);
  ps.boundsMin = glm::dvec3(-2.0, -0.5, -2.0);
  ps.boundsMax = glm::dvec3(2.0, 0.9, 2.0);
  ps.samples = 512;
  ps.bounces = 1;
  ps.threads = 1;
  const ProbeGrid a = bake::bakeProbes(r.scene, t.perMeshLowerOrder, ps);
  ps.threads = 2;
  const ProbeGrid b = bake::bakeProbes(r.scene, t.perMeshLowerOrder, ps);
  ASSERT_EQ(a.probeCount(), 18u);  // all valid under the double-sided roof
  ASSERT_EQ(a.transfer.size(), b.transfer.size());
  EXPECT_EQ(0, std::memcmp(a.transfer.data(), b.transfer.data(), a.transfer.size() * sizeof(float)));
}

TEST(SceneTwoSided, BackTransferRoundTripsThroughTheBakedFile) {
  // A double-sided plane and a one-sided one, written as glTF, loaded, baked, written as a
  // baked .glb and read back: the double-sided primitive carries _PRT_SH_BACK_ with the bake's
  // back half, the one-sided one none.
  test::TempDir d;
  test::GltfFile f;
  f.j["materials"] = {{{"doubleSided", true}, {"pbrMetallicRoughness", {{"metallicFactor", 0}}}},
                      {{"doubleSided", false}, {"pbrMetallicRoughness", {{"metallicFactor", 0}}}}};
  const int m0 = f.mesh(test::makePlane(glm::vec3(0.0f), 1.0f, 2), 0);
  const int m1 = f.mesh(test::makePlane(glm::vec3(0.0f), 1.0f, 1), 1);
  f.node({{"mesh", m0}}, true);
  f.node({{"mesh", m1}, {"translation", {0.0, -3.0, 0.0}}}, true);
  const std::string in = f.write("two_sided", d.path());
  Scene s = loadScene(in);
  ASSERT_EQ(s.meshes.size(), 2u);
  bake::BakeSettings bs;
  bs.samples = 64;
  bs.bounces = 1;
  bs.bands = 2;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  const size_t V = s.meshes[0].vertexCount();
  ASSERT_EQ(t.perMesh[0].size(), 2 * V * 4);
  ASSERT_EQ(t.perMesh[1].size(), s.meshes[1].vertexCount() * 4);
  const std::vector<glm::vec3> front(t.perMesh[0].begin(), t.perMesh[0].begin() + V * 4),
      back(t.perMesh[0].begin() + V * 4, t.perMesh[0].end()), other = t.perMesh[1];
  bake::storeTransfer(s, std::move(t.perMesh));
  EXPECT_TRUE(sameBits(s.meshes[0].transfer, front));
  EXPECT_TRUE(sameBits(s.meshes[0].transferBack, back));
  EXPECT_TRUE(sameBits(s.meshes[1].transfer, other));
  EXPECT_TRUE(s.meshes[1].transferBack.empty());
  s.transferBands = 2;
  BakeRecord record = bake::bakeRecord(bs, "two_sided.gltf", "test");
  const std::string out = d.file("baked.glb");
  EXPECT_THROW(writeBakedScene(in, s, &record, out), Error);  // the record must say so
  record.backTransfer = true;
  writeBakedScene(in, s, &record, out);
  const Scene r = loadScene(out);
  ASSERT_TRUE(r.bakeRecord);
  EXPECT_TRUE(r.bakeRecord->backTransfer);
  ASSERT_EQ(r.meshes.size(), 2u);
  EXPECT_TRUE(sameBits(r.meshes[0].transfer, s.meshes[0].transfer));
  EXPECT_TRUE(sameBits(r.meshes[0].transferBack, s.meshes[0].transferBack));
  EXPECT_TRUE(r.meshes[0].hasBackTransfer());
  EXPECT_FALSE(r.meshes[1].hasBackTransfer());
  EXPECT_TRUE(sameBits(r.meshes[1].transfer, s.meshes[1].transfer));

  // The lit file: _RADIANCE the front's radiance (COLOR_0 the same clamped to 0..1),
  // _PRT_COLOR_BACK the back's, on the double-sided primitive only.
  const sh::ShRgb sky = stepSky(2, 1.0, 0.25);
  const std::vector<std::vector<glm::vec3>> frontLit = relightVertices(r, sky), backLit = relightBackVertices(r, sky);
  ASSERT_EQ(backLit[0].size(), V);
  EXPECT_TRUE(backLit[1].empty());
  // White: π·1 from above; π·0.25 from below, a little more where the lower plane (F ≈ 0.035,
  // radiance ≈ 1) hides the sky.
  EXPECT_NEAR(frontLit[0][0].g, 1.0, 0.02);
  EXPECT_NEAR(backLit[0][0].g, 0.25, 0.05);
  const std::string lit = d.file("lit.glb");
  writeLitScene(out, r, frontLit, lit, &backLit);
  const std::string bytes = test::fileBytes(lit);
  uint32_t length = 0;
  ASSERT_GT(bytes.size(), 20u);
  std::memcpy(&length, bytes.data() + 12, 4);
  const nlohmann::json j = nlohmann::json::parse(bytes.substr(20, length));
  int withBack = 0;
  for (const auto& node : j["nodes"])  // the meshes the scene uses (mesh 0 is GltfFile's spare)
    for (const auto& prim : j["meshes"][node["mesh"].get<size_t>()]["primitives"]) {
      EXPECT_TRUE(prim["attributes"].contains("_RADIANCE"));
      EXPECT_TRUE(prim["attributes"].contains("COLOR_0"));
      withBack += prim["attributes"].contains("_PRT_COLOR_BACK");
    }
  EXPECT_EQ(withBack, 1);
}

TEST(SceneTwoSided, BackTransferWithoutAMatchingFrontSetIsRefused) {
  // Back attributes need the front set of as many bands: one back coefficient beside none, or
  // beside four front ones, refuses the file naming the primitive and the attributes.
  test::TempDir d;
  for (int front : {0, 4}) {
    test::GltfFile f;
    const int m = f.mesh({0, 0, 0, 1, 0, 0, 0, 0, 1}, {0, 1, 0, 0, 1, 0, 0, 1, 0}, {0, 2, 1});
    auto& attributes = f.j["meshes"][size_t(m)]["primitives"][0]["attributes"];
    const std::vector<float> zero(9, 0.0f);
    for (int i = 0; i < front; ++i) attributes[cat("_PRT_SH_0", i)] = f.accessor(zero, "VEC3");
    attributes["_PRT_SH_BACK_00"] = f.accessor(zero, "VEC3");
    f.node({{"mesh", m}}, true);
    const std::string path = f.write(cat("bad_back_", front), d.path());
    try {
      loadScene(path);
      ADD_FAILURE() << "loaded with " << front << " front coefficients";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("mesh 1 / primitive 0: 1 back-side transfer attributes (_PRT_SH_BACK_NN), but " +
                          std::to_string(front) + " front ones"),
                std::string::npos)
          << what;
    }
  }
}

}  // namespace
}  // namespace prt
