// Buried vertices (bake/src/unbury.h, docs/bake.md "Buried vertices"): a vertex inside other
// geometry has its rays start just past the surface that buries it, on its own triangles, in
// the bake, refinement and the direct lights' shadows alike; a vertex under a table stays.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "baked_scene.h"
#include "prt/bake/direct_light.h"
#include "prt/bake/refine.h"
#include "prt/bake/surface_bake.h"
#include "prt/light.h"
#include "prt/math.h"
#include "test_scenes.h"

namespace prt {
namespace {

constexpr double kY00 = 0.28209479177387814;  // y_00 = 1 / (2√π)

// A wall x, y ∈ [−1, 1] in the plane z = 0 facing +Z, two triangles, its lower half sunk into a
// block x, z ∈ [−100, 100], y ∈ [−3, 0] whose faces face out (a house's wall in the terrain).
Scene sunkWall() {
  MeshInstance wall;
  wall.name = "wall";
  for (glm::vec3 p : {glm::vec3(-1, -1, 0), glm::vec3(1, -1, 0), glm::vec3(1, 1, 0), glm::vec3(-1, 1, 0)}) {
    wall.positions.push_back(p);
    wall.normals.push_back({0, 0, 1});
  }
  test::addTriangle(wall, 0, 1, 2, {0, 0, 1});
  test::addTriangle(wall, 0, 2, 3, {0, 0, 1});
  MeshInstance block;
  block.name = "block";
  const glm::vec3 lo(-100, -3, -100), hi(100, 0, 100);
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      glm::vec3 n(0.0f);
      n[axis] = side ? 1.0f : -1.0f;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const uint32_t first = uint32_t(block.positions.size());
      for (int k = 0; k < 4; ++k) {
        glm::vec3 p;
        p[axis] = side ? hi[axis] : lo[axis];
        p[u] = (k == 1 || k == 2) ? hi[u] : lo[u];
        p[v] = (k >= 2) ? hi[v] : lo[v];
        block.positions.push_back(p);
        block.normals.push_back(n);
      }
      test::addTriangle(block, first, first + 1, first + 2, n);
      test::addTriangle(block, first, first + 2, first + 3, n);
    }
  return test::makeScene({wall, block}, 0.5f);
}

// The irradiance under a uniform sky of radiance 1 from a vertex's transfer: t_00 · 2√π.
double skyIrradiance(const std::vector<glm::vec3>& t, int n2, size_t v) { return t[v * size_t(n2)].y / kY00; }

TEST(BakeUnbury, ABuriedWallFootStandsForItsVisibleWall) {
  // Above a wide block, a vertical wall sees the sky above the horizon and the block's top
  // below it: π/2 at every height (the block's far edge, 100 m away, lets through a band of
  // about 1° below the horizon: +1.3% at the top, less below). The foot's vertices lie inside
  // the block, where every ray meets a face from behind: without being moved they would measure
  // 0, and the wall's visible half would shade from π/4 to π/2. Tolerance 5%: 1024 cosine rays
  // of a half-blocked hemisphere give about 1.6% of standard error, plus the band.
  const Scene s = sunkWall();
  bake::BakeSettings bs;
  bs.samples = 1024;
  bs.bounces = 0;
  const bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  const int n2 = bs.bands * bs.bands;
  for (size_t v = 0; v < 4; ++v)
    EXPECT_NEAR(skyIrradiance(t.perMesh[0], n2, v), kPi / 2.0, 0.05 * kPi / 2.0) << "wall vertex " << v;
}

TEST(BakeUnbury, AVertexUnderATableStays) {
  // A floor under a one-sided table top (half-size 1, 0.5 above it, facing up): the floor's
  // centre sees the table's underside on most of its rays, so it is buried by the count, but
  // no ray along the floor crosses the table, and it keeps its own place: its irradiance under
  // a uniform sky is π (1 − F), F the table's form factor (closed form by quadrature), not the
  // open floor's π it would get moved out. Tolerance 0.03 π: the noise of 1024 rays.
  MeshInstance table = test::makePlane({0, 0.5f, 0}, 2.0f, 1);
  const Scene s = test::makeScene({test::makePlane({0, 0, 0}, 8.0f, 8), table}, 0.5f);
  bake::BakeSettings bs;
  bs.samples = 1024;
  bs.bounces = 0;
  const bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  const int n = 2000;
  const double a = 1.0, h = 0.5, d = 2.0 * a / n;
  double f = 0.0;
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < n; ++k) {
      const double x = -a + (i + 0.5) * d, z = -a + (k + 0.5) * d, q = x * x + z * z + h * h;
      f += h * h / (q * q) * d * d / kPi;
    }
  const size_t centre = 4 * 9 + 4;
  ASSERT_GT(f, 0.5);  // the centre is buried by the count
  EXPECT_NEAR(skyIrradiance(t.perMesh[0], bs.bands * bs.bands, centre), kPi * (1.0 - f), 0.03 * kPi);
}

TEST(BakeUnbury, TheSunLightsTheMovedFootAsTheWall) {
  // The direct lights' shadow rays leave from the same moved origins: a sun 45° above the
  // horizon in front of the wall lights all four vertices alike, E cos 45°; from inside the
  // block the foot would be in shadow.
  Scene s = sunkWall();
  test::bakeInPlace(s, 16, 2, 1);
  DirectLight sun;
  sun.direction = glm::normalize(glm::dvec3(0.0, 1.0, 1.0));
  sun.irradiance = glm::dvec3(2.0);
  const bake::DirectIrradiance d = bake::shadowedDirectIrradiance(s, {sun});
  for (size_t v = 0; v < 4; ++v) EXPECT_NEAR(d.front[0][v].x, 2.0 * std::sqrt(0.5), 1e-4) << "wall vertex " << v;
}

TEST(BakeUnbury, RefinementLeavesTheSunkWallWhole) {
  // Refinement measures with the moved origins too: the wall's visible half is uniform, so no
  // edge of the wall is split (measured from inside the block, the foot against the top is an
  // error of half the transfer: the wall came out of refinement with 26 vertices).
  Scene s = sunkWall();
  bake::RefineSettings rs;
  rs.tolerance = 0.02;
  bake::BakeSettings bs;
  bs.samples = 256;
  bake::refineScene(s, rs, bs);
  EXPECT_EQ(s.meshes[0].vertexCount(), 4u);
}

}  // namespace
}  // namespace prt
