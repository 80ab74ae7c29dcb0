// Adaptive refinement (prt/bake/refine.h) against a finely tessellated bake of the same
// surface: a coarse quad under an occluder, refined and baked, must light like the fine quad;
// surfaces with nothing to gain are left alone; the budget holds; any thread count gives the
// same mesh. The file side (the refined .glb, read back) is in test_cli_refine.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include "gltf_file.h"
#include "harness.h"
#include "prt/bake/refine.h"
#include "prt/bake/surface_bake.h"
#include "prt/math.h"
#include "prt/scene.h"
#include "test_scenes.h"

namespace prt {
namespace {

using test::GltfFile;

// The floor: [-1, 1]² at y = 0 facing +Y as an n × n grid; with `occluder`, a 1 × 1 square at
// height 0.3 over x ∈ [-0.25, 0.75], z ∈ [-0.5, 0.5], facing down: its shadow under the sky
// has edges inside the floor's two coarse triangles.
std::string quadScene(const test::TempDir& dir, const std::string& name, int n, bool occluder) {
  GltfFile f;
  MeshInstance floor = test::makePlane({0, 0, 0}, 2.0f, n);
  f.node({{"name", "Floor"}, {"mesh", f.mesh(floor)}}, true);
  if (occluder) {
    MeshInstance lid = test::makePlane({0.25f, 0.3f, 0.0f}, 1.0f, 1);
    for (glm::vec3& nn : lid.normals) nn = {0, -1, 0};
    for (size_t t = 0; t < lid.indices.size(); t += 3) std::swap(lid.indices[t + 1], lid.indices[t + 2]);
    f.node({{"name", "Lid"}, {"mesh", f.mesh(lid)}}, true);
  }
  return f.write(name, dir.path());
}

// Irradiance under a uniform sky of radiance 1 (l_0 = √(4π)), interpolated from the vertices of
// `m` at (x, z) on the floor, as the renderer interpolates it: barycentrics of the triangle
// that holds the point.
double skyIrradianceAt(const MeshInstance& m, const std::vector<glm::vec3>& transfer, int bands, double x, double z) {
  const size_t n2 = size_t(bands) * size_t(bands);
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    const glm::dvec3 a(m.positions[m.indices[3 * t]]), b(m.positions[m.indices[3 * t + 1]]),
        c(m.positions[m.indices[3 * t + 2]]);
    const double det = (b.x - a.x) * (c.z - a.z) - (c.x - a.x) * (b.z - a.z);
    const double u = ((x - a.x) * (c.z - a.z) - (c.x - a.x) * (z - a.z)) / det;
    const double v = ((b.x - a.x) * (z - a.z) - (x - a.x) * (b.z - a.z)) / det;
    if (u < -1e-9 || v < -1e-9 || u + v > 1 + 1e-9) continue;
    const double e = (1 - u - v) * transfer[m.indices[3 * t] * n2].r + u * transfer[m.indices[3 * t + 1] * n2].r +
                     v * transfer[m.indices[3 * t + 2] * n2].r;
    return e * std::sqrt(4.0 * prt::kPi);
  }
  ADD_FAILURE() << "(" << x << ", " << z << ") is on no triangle";
  return 0.0;
}

struct Baked {
  Scene scene;
  bake::SurfaceTransfer transfer;
  bake::RefineStats refined;
};

Baked bakeQuad(const std::string& path, const bake::RefineSettings& refine, int threads = 0) {
  Baked b;
  b.scene = loadScene(path);
  bake::BakeSettings s;
  s.samples = 1024;
  s.bounces = 0;
  s.threads = threads;
  b.refined = bake::refineScene(b.scene, refine, s);
  b.transfer = bake::bakeSurface(b.scene, s);
  return b;
}

// Largest and mean |E − E_fine| / π over a 41 × 41 grid of the floor.
std::pair<double, double> irradianceError(const Baked& b, const Baked& fine) {
  double worst = 0.0, sum = 0.0;
  int n = 0;
  for (int i = 0; i <= 40; ++i)
    for (int j = 0; j <= 40; ++j) {
      const double x = -0.98 + 1.96 * i / 40.0, z = -0.98 + 1.96 * j / 40.0;
      const double e = skyIrradianceAt(b.scene.meshes[0], b.transfer.perMesh[0], 3, x, z);
      const double ef = skyIrradianceAt(fine.scene.meshes[0], fine.transfer.perMesh[0], 3, x, z);
      worst = std::max(worst, std::abs(e - ef) / prt::kPi);
      sum += std::abs(e - ef) / prt::kPi;
      ++n;
    }
  return {worst, sum / n};
}

// A convex UV sphere of radius 1, smooth normals, `segments` × `rings`: nothing occludes it.
MeshInstance coarseSphere(int segments, int rings) {
  MeshInstance m;
  for (int r = 0; r <= rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const double theta = prt::kPi * r / rings, phi = 2 * prt::kPi * s / segments;
      const glm::vec3 p(float(std::sin(theta) * std::cos(phi)), float(std::cos(theta)),
                        float(std::sin(theta) * std::sin(phi)));
      m.positions.push_back(p);
      m.normals.push_back(p);
    }
  for (int r = 0; r < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const uint32_t a = uint32_t(r * segments + s), b = uint32_t(r * segments + (s + 1) % segments);
      const uint32_t c = a + uint32_t(segments), d = b + uint32_t(segments);
      const glm::vec3 out = m.positions[a] + m.positions[d];
      if (r > 0) test::addTriangle(m, a, b, d, out);
      if (r + 1 < rings) test::addTriangle(m, a, d, c, out);
    }
  return m;
}

bake::RefineSettings off() {
  bake::RefineSettings r;
  r.tolerance = 0.0;
  return r;
}

// The refined coarse quad against a 48 × 48 bake of the same floor. Bound: a score |e|/R ≤ τ
// (R = |t_unoccluded|) bounds the DC error by τR, and a uniform sky of radiance 1 (l_0 = √4π)
// turns it into |ΔE|/π ≤ τ R √(4π)/π = 1.62 τ (3 bands); on top, both bakes' noise at 1024
// samples: a half-shadowed vertex has σ(E/π) ≈ 1.13 · 0.89 · 0.5/√1024 = 0.016, 2σ = 0.03
// each. The unrefined quad misses the shadow (its worst error ~0.76): the test can fail.
TEST(BakeRefine, CoarseQuadUnderAnOccluderMatchesAFineBake) {
  const test::TempDir dir("refine_quad");
  const Baked fine = bakeQuad(quadScene(dir, "fine", 48, true), off());
  const std::string coarse = quadScene(dir, "coarse", 1, true);
  const Baked raw = bakeQuad(coarse, off());
  const bake::RefineSettings r;  // the defaults
  const Baked refined = bakeQuad(coarse, r);
  const auto [rawWorst, rawMean] = irradianceError(raw, fine);
  const auto [worst, mean] = irradianceError(refined, fine);
  const double bound = 1.62 * r.tolerance + 2 * 0.03;
  EXPECT_GT(refined.refined.verticesAfter, refined.refined.verticesBefore);
  EXPECT_LE(refined.refined.residual, r.tolerance);
  EXPECT_GT(rawWorst, bound);
  EXPECT_LE(worst, bound) << "unrefined " << rawWorst << ", " << refined.refined.verticesAfter << " vertices";
  EXPECT_LT(mean, rawMean / 5);
  EXPECT_LE(refined.refined.verticesAfter, fine.refined.verticesAfter / 10);  // far fewer than the fine bake
}

// Both sides of a double-sided floor are refined: the lid is *under* the floor, so only the
// floor's back side (normal −Y, its own rays) has a shadow edge, and the front sees the whole
// sky. The refined coarse floor's back side matches a 48 × 48 bake within the bound above;
// measured on the front side only (as refinement did before), nothing would be added.
TEST(BakeRefine, DoubleSidedFloorIsRefinedForItsBackSide) {
  const test::TempDir dir("refine_back");
  auto scene = [&](const std::string& name, int n) {
    GltfFile f;
    f.j["materials"] = {{{"doubleSided", true}, {"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.5, 0.5, 1.0}}}}}};
    MeshInstance floor = test::makePlane({0, 0, 0}, 2.0f, n);
    f.node({{"name", "Floor"}, {"mesh", f.mesh(floor, 0)}}, true);
    MeshInstance lid = test::makePlane({0.25f, -0.3f, 0.0f}, 1.0f, 1);  // facing up, at the floor's back
    f.node({{"name", "Lid"}, {"mesh", f.mesh(lid)}}, true);
    return f.write(name, dir.path());
  };
  auto backOf = [](const Baked& b) {  // the floor's back-side transfer: the second half
    const std::vector<glm::vec3>& t = b.transfer.perMesh[0];
    return std::vector<glm::vec3>(t.begin() + ptrdiff_t(t.size() / 2), t.end());
  };
  const Baked fine = bakeQuad(scene("fine", 48), off());
  const std::string coarse = scene("coarse", 1);
  const Baked raw = bakeQuad(coarse, off());
  const bake::RefineSettings r;
  const Baked refined = bakeQuad(coarse, r);
  ASSERT_EQ(fine.transfer.perMesh[0].size(), 2 * fine.scene.meshes[0].vertexCount() * 9);
  EXPECT_GT(refined.refined.verticesAfter, refined.refined.verticesBefore);
  double rawWorst = 0.0, worst = 0.0;
  const std::vector<glm::vec3> fb = backOf(fine), rb = backOf(raw), cb = backOf(refined);
  for (int i = 0; i <= 40; ++i)
    for (int j = 0; j <= 40; ++j) {
      const double x = -0.98 + 1.96 * i / 40.0, z = -0.98 + 1.96 * j / 40.0;
      const double ef = skyIrradianceAt(fine.scene.meshes[0], fb, 3, x, z);
      rawWorst = std::max(rawWorst, std::abs(skyIrradianceAt(raw.scene.meshes[0], rb, 3, x, z) - ef) / prt::kPi);
      worst = std::max(worst, std::abs(skyIrradianceAt(refined.scene.meshes[0], cb, 3, x, z) - ef) / prt::kPi);
    }
  const double bound = 1.62 * r.tolerance + 2 * 0.03;
  EXPECT_GT(rawWorst, bound);
  EXPECT_LE(worst, bound) << "unrefined " << rawWorst << ", " << refined.refined.verticesAfter << " vertices";
}

// Nothing to gain, nothing added: a quad that sees the whole sky, a fine floor, and a curved
// unoccluded surface (a coarse dome whose normals vary: the normals' own interpolation does not
// count).
TEST(BakeRefine, UnoccludedAndFineMeshesAreLeftAlone) {
  const test::TempDir dir("refine_alone");
  for (const std::string& path : {quadScene(dir, "open", 1, false), test::sourcePath("scenes/plane.gltf")}) {
    SCOPED_TRACE(path);
    const Baked b = bakeQuad(path, bake::RefineSettings{});
    EXPECT_EQ(b.refined.verticesAfter, b.refined.verticesBefore);
    EXPECT_TRUE(b.scene.meshes[0].fileBlend.empty());
  }
  GltfFile f;
  MeshInstance dome = coarseSphere(6, 4);
  f.node({{"name", "Dome"}, {"mesh", f.mesh(dome)}}, true);
  const Baked b = bakeQuad(f.write("dome", dir.path()), bake::RefineSettings{});
  EXPECT_EQ(b.refined.verticesAfter, b.refined.verticesBefore);
}

TEST(BakeRefine, ScaleLeavesAFarGroundPlaneOut) {
  // A 2 × 2 m floor of 32 × 32 cells (1089 vertices) and a 2 km ground plane of 4 vertices
  // around it: the bounding box's diagonal is 2.8 km, the refinement's scale the floor's 2.8 m
  // (its 1%–99% box), so edges of the floor are not "short" against the ground plane.
  Scene s = test::makeScene({test::makePlane({0, 0, 0}, 2.0f, 32), test::makePlane({0, -1, 0}, 2000.0f, 1)}, 0.5f);
  EXPECT_NEAR(bake::refineScale(s), 2.0 * std::sqrt(2.0), 1e-5);
  s.meshes[1].receiverOnly = true;  // receivers are not refined, nor measured
  s.meshes.erase(s.meshes.begin());
  EXPECT_EQ(bake::refineScale(s), 0.0);
}

TEST(BakeRefine, BudgetIsRespected) {
  const test::TempDir dir("refine_budget");
  const std::string coarse = quadScene(dir, "coarse", 1, true);
  bake::RefineSettings r;
  r.budget = 5;
  const Baked b = bakeQuad(coarse, r);
  EXPECT_GT(b.refined.verticesAfter, b.refined.verticesBefore);
  EXPECT_LE(b.refined.verticesAfter, b.refined.verticesBefore + 5);
  EXPECT_TRUE(b.refined.budgetReached);
  r.budget = 0;  // automatic: at least kMinAutoBudget
  EXPECT_EQ(bake::refineBudget(r, b.scene), bake::kMinAutoBudget);
}

// Conforming: every edge of the refined floor is shared by two of its triangles or lies on the
// quad's border, and each vertex interpolates the file's corners with weights that reproduce
// its position.
TEST(BakeRefine, RefinedMeshIsConformingAndItsBlendsReproducePositions) {
  const test::TempDir dir("refine_mesh");
  const Baked b = bakeQuad(quadScene(dir, "coarse", 1, true), bake::RefineSettings{});
  const MeshInstance& m = b.scene.meshes[0];
  ASSERT_GT(m.vertexCount(), 4u);
  std::map<std::pair<uint32_t, uint32_t>, int> edges;
  for (size_t t = 0; t < m.triangleCount(); ++t)
    for (int j = 0; j < 3; ++j) {
      uint32_t a = m.indices[3 * t + size_t(j)], c = m.indices[3 * t + size_t(j + 1) % 3];
      edges[{std::min(a, c), std::max(a, c)}]++;
    }
  for (const auto& [e, count] : edges) {
    const glm::vec3 p = m.positions[e.first], q = m.positions[e.second];
    const bool border = (std::abs(p.x) == 1 && p.x == q.x) || (std::abs(p.z) == 1 && p.z == q.z);
    EXPECT_EQ(count, border ? 1 : 2) << "edge " << e.first << "-" << e.second;
  }
  ASSERT_EQ(m.fileBlend.size(), m.vertexCount());
  const MeshInstance original = loadScene(quadScene(dir, "coarse", 1, true)).meshes[0];
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    glm::vec3 p(0.0f), n(0.0f);
    float sum = 0.0f;
    for (int j = 0; j < 3; ++j) {
      p += m.fileBlend[v].weight[j] * original.positions[m.fileBlend[v].vertex[j]];
      sum += m.fileBlend[v].weight[j];
    }
    EXPECT_NEAR(sum, 1.0f, 1e-6f);
    EXPECT_NEAR(glm::length(p - m.positions[v]), 0.0f, 1e-6f) << "vertex " << v;
    EXPECT_NEAR(glm::length(m.normals[v]), 1.0f, 1e-5f);
  }
}

TEST(BakeRefine, SameMeshForAnyThreadCount) {
  const test::TempDir dir("refine_threads");
  const std::string coarse = quadScene(dir, "coarse", 1, true);
  const Baked one = bakeQuad(coarse, bake::RefineSettings{}, 1);
  const Baked two = bakeQuad(coarse, bake::RefineSettings{}, 2);
  for (size_t k = 0; k < one.scene.meshes.size(); ++k) {
    EXPECT_EQ(one.scene.meshes[k].positions, two.scene.meshes[k].positions);
    EXPECT_EQ(one.scene.meshes[k].indices, two.scene.meshes[k].indices);
  }
  EXPECT_EQ(one.refined.residual, two.refined.residual);
}

}  // namespace
}  // namespace prt
