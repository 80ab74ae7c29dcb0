// Direct lights (suns, small disks) split off the SH light: the clipped-cap closed form, exact
// shadowed irradiance with shadow rays (a plane under a sun, a penumbra across a straight edge
// against quadrature), the transfer's direct part on surfaces and probes, and the relight split.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "harness.h"
#include "prt/bake/direct_light.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/surface_bake.h"
#include "prt/light.h"
#include "prt/light_rig.h"
#include "prt/math.h"
#include "prt/probe_grid.h"
#include "prt/relight.h"
#include "prt/sh.h"
#include "test_scenes.h"

namespace prt {
namespace {

DirectLight sunAt(double zenithDegrees, double azimuthDegrees, double radiusDegrees, glm::dvec3 e) {
  DirectLight l;
  const double t = glm::radians(zenithDegrees), p = glm::radians(azimuthDegrees);
  l.direction = glm::dvec3(std::sin(t) * std::sin(p), std::cos(t), std::sin(t) * std::cos(p));
  l.radius = glm::radians(radiusDegrees);
  l.irradiance = e;
  return l;
}

// ∫_cap g(ω) dω by the midpoint rule in (cos θ', φ) about the light's axis (uniform in solid
// angle): n × n cells of equal solid angle.
template <class F>
double capQuadrature(const DirectLight& l, int n, F g) {
  const glm::dvec3 d = l.direction;
  const glm::dvec3 a = std::fabs(d.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
  const glm::dvec3 t = glm::normalize(glm::cross(a, d)), b = glm::cross(d, t);
  const double oneMinusCos = 1.0 - std::cos(l.radius), cell = 2.0 * prt::kPi * oneMinusCos / (double(n) * n);
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const double c = 1.0 - (i + 0.5) / n * oneMinusCos, s = std::sqrt(1.0 - c * c);
    for (int j = 0; j < n; ++j) {
      const double phi = 2.0 * prt::kPi * (j + 0.5) / n;
      sum += g(c * d + s * std::cos(phi) * t + s * std::sin(phi) * b);
    }
  }
  return sum * cell;
}

// The clipped cap (Note 4 of light.cpp) against quadrature, above, across and below the
// horizon. 1000² cells: the integrand has a kink at the horizon, so the midpoint rule's error
// is O(1/n) on the band that straddles it: a few 1e-5 of the facing value, measured; 2e-4 is
// far below any wrong branch (≥ 1e-2 near the horizon).
TEST(LightDirect, CosineFactorMatchesQuadratureAcrossTheHorizon) {
  for (double r : {0.5, 5.0, 20.0})
    for (double zenith : {0.0, 30.0, 80.0, 88.0, 89.9, 90.0, 92.0, 95.0, 109.0, 111.0}) {
      const DirectLight l = sunAt(zenith, 0.0, r, glm::dvec3(1.0));
      const glm::dvec3 n(0, 1, 0);
      const double exact = capQuadrature(l, 1000, [&](const glm::dvec3& w) { return std::max(glm::dot(n, w), 0.0); }) /
                           (prt::kPi * std::sin(l.radius) * std::sin(l.radius));
      EXPECT_NEAR(directCosineFactor(l, n), exact, 2e-4) << "radius " << r << ", zenith " << zenith;
    }
  // A delta: the plain cosine.
  EXPECT_DOUBLE_EQ(directCosineFactor(sunAt(60.0, 0.0, 0.0, glm::dvec3(1.0)), {0, 1, 0}), std::cos(glm::radians(60.0)));
}

// A lone plane under a sun: nothing occludes it and nothing reflects onto it, so the split
// relight gives exactly (ρ/π) E cos θ (the ratio estimator is exact without occluders and
// t − t⁰ = 0 without bounces), and 0 once the sun is below the horizon; the horizon-straddling
// sun gets the clipped factor. Float rounding only: 1e-5.
TEST(BakeDirectLight, PlaneUnderASunIsExact) {
  const float rho = 0.5f;
  Scene s = test::makeScene({test::makePlane({0, 0, 0}, 2.0f, 4)}, rho);
  bake::BakeSettings bs;
  bs.samples = 64;
  bs.bounces = 2;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  ASSERT_TRUE(hasDirectTransfer(s));
  const glm::dvec3 e(2.0, 1.5, 1.0);
  for (double zenith : {0.0, 40.0, 89.0, 91.0, 100.0})
    for (double radius : {0.0, 0.265, 5.0}) {
      const DirectLight sun = sunAt(zenith, 30.0, radius, e);
      bake::DirectIrradiance d = bake::shadowedDirectIrradiance(s, {sun});
      const double factor = directCosineFactor(sun, {0, 1, 0});
      const sh::ShRgb shSun = sun.project(3);
      const auto lit = relightVerticesSplit(s, sh::ShRgb(3), shSun, d.front);
      for (size_t v = 0; v < s.meshes[0].vertexCount(); ++v)
        for (int c = 0; c < 3; ++c) {
          const double expected = rho / prt::kPi * e[c] * factor;
          ASSERT_NEAR(d.front[0][v][c], e[c] * factor, 1e-5 * e[c]) << "zenith " << zenith << " radius " << radius;
          ASSERT_NEAR(lit[0][v][c], expected, 1e-5 * e[c]) << "zenith " << zenith << " radius " << radius;
        }
    }
}

// A disk light's penumbra across a straight edge: a floor at y = 0 under a roof slab over
// x < 0 (its underside at y = 1), a disk of radius 10° at 30° from the zenith towards +x. The
// shadowed irradiance at floor vertices across the penumbra, against quadrature over the cap
// with the roof's analytic occlusion (ray to the plane y = 1, blocked where it meets x < 0).
// 1024 stratified samples estimate a visible share to ~0.3% (measured: worst 0.6%, mean 0.02%); 1% of the
// facing irradiance bounds it, while a wrong cosine weighting or cap sampling is off by > 3%.
TEST(BakeDirectLight, PenumbraAcrossAStraightEdgeMatchesQuadrature) {
  MeshInstance floor = test::makePlane({0, 0, 0}, 4.0f, 40);
  Scene s = test::makeScene({floor, test::makeSlab({-3.0f, 1.0f, -3.0f}, {0.0f, 1.05f, 3.0f})}, 0.5f);
  bake::BakeSettings bs;
  bs.samples = 16;
  bs.bounces = 0;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  const DirectLight disk = sunAt(30.0, 90.0, 10.0, glm::dvec3(1.0));
  bake::ShadowSettings ss;
  ss.samples = 1024;
  bake::DirectIrradiance d = bake::shadowedDirectIrradiance(s, {disk}, ss);
  const double L = 1.0 / (prt::kPi * std::sin(disk.radius) * std::sin(disk.radius));
  double worst = 0.0, meanError = 0.0;
  int penumbra = 0, checked = 0;
  for (size_t v = 0; v < s.meshes[0].vertexCount(); ++v) {
    const glm::dvec3 p(s.meshes[0].positions[v]);
    if (std::fabs(p.z) > 1.0) continue;
    const double ref = L * capQuadrature(disk, 300, [&](const glm::dvec3& w) {
                         const double xHit = p.x + w.x / w.y;  // where the ray meets y = 1
                         return xHit < 0.0 ? 0.0 : std::max(w.y, 0.0);
                       });
    const double got = d.front[0][v].g;
    worst = std::max(worst, std::fabs(got - ref));
    meanError += std::fabs(got - ref);
    ++checked;
    penumbra += ref > 0.02 && ref < 0.98 * directCosineFactor(disk, {0, 1, 0});
  }
  meanError /= checked;
  std::printf("[ measured ] penumbra: %d of %d vertices in it, worst error %.4f, mean %.5f (of E = 1)\n", penumbra,
              checked, worst, meanError);
  EXPECT_GE(penumbra, 40);  // the test crosses the penumbra: about 1 m of it at 0.1 m spacing, 21 rows
  EXPECT_LT(worst, 0.01);
  EXPECT_LT(meanError, 0.003);
}

TEST(BakeDirectLight, SameBitsForAnyThreadCount) {
  Scene s =
      test::makeScene({test::makePlane({0, 0, 0}, 4.0f, 20), test::makeSlab({-1, 0.5f, -1}, {0.3f, 0.6f, 1})}, 0.5f);
  bake::BakeSettings bs;
  bs.samples = 16;
  bs.bounces = 0;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  const std::vector<DirectLight> lights = {sunAt(20.0, 10.0, 2.0, glm::dvec3(3.0)),
                                           sunAt(50.0, 200.0, 0.0, glm::dvec3(1.0))};
  bake::ShadowSettings one, two;
  one.threads = 1;
  two.threads = 2;
  const auto a = bake::shadowedDirectIrradiance(s, lights, one), b = bake::shadowedDirectIrradiance(s, lights, two);
  for (size_t k = 0; k < s.meshes.size(); ++k) {
    ASSERT_EQ(a.front[k].size(), b.front[k].size());
    EXPECT_EQ(0, std::memcmp(a.front[k].data(), b.front[k].data(), a.front[k].size() * sizeof(glm::vec3)));
  }
}

// The surface bake's direct part is its bounce-0 transfer: with no bounce the total is the
// direct part in every channel, bit for bit; with bounces the total exceeds it by what the
// bounces add (the cavity's walls light each other).
TEST(BakeDirectLight, SurfaceDirectPartIsTheFirstBounce) {
  Scene s = test::makeScene({test::makeCavity(prt::kPi / 3.0, 12, 24)}, 0.8f);
  bake::BakeSettings bs;
  bs.samples = 128;
  bs.bounces = 0;
  const bake::SurfaceTransfer t0 = bake::bakeSurface(s, bs);
  bs.bounces = 3;
  const bake::SurfaceTransfer t3 = bake::bakeSurface(s, bs);
  ASSERT_EQ(t0.perMeshDirect[0].size(), t0.perMesh[0].size());
  for (size_t i = 0; i < t0.perMesh[0].size(); ++i) {
    ASSERT_EQ(t0.perMeshDirect[0][i], t0.perMesh[0][i].r);
    ASSERT_EQ(t0.perMeshDirect[0][i], t0.perMesh[0][i].b);
    ASSERT_EQ(t3.perMeshDirect[0][i], t0.perMeshDirect[0][i]);  // the same rays
  }
  // Coefficient 0 of a cavity vertex: the walls add ρ f/(1 − ρ(1 − f))-ish to the sky's share.
  EXPECT_GT(t3.perMesh[0][0].g, 1.2f * t3.perMeshDirect[0][0]);
}

// The gather of direct lights' bounces is the surface bake's own bounce operator: with as many
// rays as the bake and its seed it casts the bake's rays, so fed with E⁰ = t⁰ · l for an SH
// light l it returns the bake's bounced part (t − t⁰) · l. A room of a cavity and a slab,
// double-sided (back sides bounce too) and coloured, 3 bounces: equal to float rounding and
// the hit records' 16-bit barycentrics (1e-4 of the total), while a wrong albedo, seed, side or
// bounce count is off by percents. With fewer rays it is the same estimator with more noise.
TEST(BakeDirectBounce, GatherWithTheBakesRaysIsTheBakesBouncedTransfer) {
  Scene s = test::makeScene(
      {test::makeCavity(prt::kPi / 2.5, 12, 24), test::makeSlab({-0.3f, -0.9f, -0.3f}, {0.3f, -0.7f, 0.3f})}, 0.7f);
  for (Material& m : s.materials) {
    m.doubleSided = true;
    m.baseColorFactor = glm::vec4(0.8f, 0.6f, 0.4f, 1.0f);
  }
  bake::BakeSettings bs;
  bs.samples = 256;
  bs.bounces = 3;
  bs.seed = 7;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  ASSERT_TRUE(hasDirectTransfer(s));
  ASSERT_TRUE(s.meshes[0].hasBackTransfer());
  sh::ShRgb l(3);
  for (int i = 0; i < 9; ++i) l.c[size_t(i)] = glm::vec3(1.0f + 0.1f * i, 0.5f - 0.05f * i, 0.3f + 0.02f * i);
  // E⁰ = t⁰ · l and the bake's bounced part (t − t⁰) · l, per side.
  bake::DirectIrradiance e0;
  std::vector<std::vector<glm::vec3>> expectFront(s.meshes.size()), expectBack(s.meshes.size());
  e0.front.resize(s.meshes.size());
  e0.back.resize(s.meshes.size());
  for (size_t k = 0; k < s.meshes.size(); ++k)
    for (int side = 0; side < 2; ++side) {
      const MeshInstance& m = s.meshes[k];
      const std::vector<glm::vec3>& total = side ? m.transferBack : m.transfer;
      auto& e = side ? e0.back[k] : e0.front[k];
      auto& expect = side ? expectBack[k] : expectFront[k];
      for (size_t v = 0; v < m.vertexCount(); ++v) {
        const float* t0 = m.directTransferOf(v, 3, side == 1);
        glm::vec3 d(0.0f), all = sh::dot(total.data() + v * 9, l.c.data(), 9);
        for (int i = 0; i < 9; ++i) d += t0[i] * l.c[size_t(i)];
        e.push_back(d);
        expect.push_back(all - d);
      }
    }
  bake::BounceSettings b;
  b.samples = bs.samples;
  b.bounces = bs.bounces;
  b.seed = bs.seed;
  const bake::DirectBounce gather(s, b);
  EXPECT_EQ(gather.rays(), uint64_t(bs.samples) * 2 * (s.meshes[0].vertexCount() + s.meshes[1].vertexCount()));
  const bake::DirectIrradiance got = gather.bounce(e0);
  double worst = 0.0, scale = 0.0, bounced = 0.0;
  for (size_t k = 0; k < s.meshes.size(); ++k)
    for (int side = 0; side < 2; ++side) {
      const auto& g = side ? got.back[k] : got.front[k];
      const auto& x = side ? expectBack[k] : expectFront[k];
      const auto& e = side ? e0.back[k] : e0.front[k];
      ASSERT_EQ(g.size(), x.size());
      for (size_t v = 0; v < g.size(); ++v)
        for (int c = 0; c < 3; ++c) {
          worst = std::max(worst, double(std::fabs(g[v][c] - x[v][c])));
          scale = std::max(scale, double(std::fabs(x[v][c] + e[v][c])));
          bounced = std::max(bounced, double(std::fabs(x[v][c])));
        }
    }
  std::printf("[ measured ] gather against the bake's bounced transfer: worst %.3g, largest bounced %.3g, total %.3g\n",
              worst, bounced, scale);
  EXPECT_GT(bounced, 0.05 * scale);  // the bounces matter here
  EXPECT_LT(worst, 1e-4 * scale);
  // Other thread counts: the same bits.
  b.threads = 1;
  const bake::DirectIrradiance one = bake::DirectBounce(s, b).bounce(e0);
  for (size_t k = 0; k < s.meshes.size(); ++k)
    EXPECT_EQ(0, std::memcmp(one.front[k].data(), got.front[k].data(), got.front[k].size() * sizeof(glm::vec3)));
  // Fewer rays: the same quantity, noisier (mean over vertices within a few percent).
  b.samples = 64;
  const bake::DirectIrradiance few = bake::DirectBounce(s, b).bounce(e0);
  double sumFew = 0.0, sumAll = 0.0;
  for (size_t v = 0; v < few.front[0].size(); ++v) {
    sumFew += few.front[0][v].g;
    sumAll += got.front[0][v].g;
  }
  EXPECT_NEAR(sumFew / sumAll, 1.0, 0.05);
}

// A probe at the centre of the open cavity: the direct part M⁰ sees the opening only, so under a
// uniform sky of radiance 1, M⁰·l is the K = 0 closed form of ProbeCavity (c_00 = y_00 Ω,
// c_1y = 0.4886 π sin²α), whatever the bounces; M⁰ is stored as its upper triangle, and
// relightProbes(l, d) = M·(l + d) − M⁰·d, checked against the matrices themselves.
TEST(ProbeDirect, CavityCentreDirectPartIsTheOpening) {
  const double alpha = prt::kPi / 3.0;
  Scene s = test::makeScene({test::makeCavity(alpha, 48, 96)}, 0.5f);
  bake::BakeSettings bs;
  bs.samples = 256;
  bs.bounces = 2;
  bs.keepLowerOrder = true;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::ProbeSettings ps;
  ps.dims = glm::ivec3(1);
  ps.boundsMin = glm::dvec3(-0.05);
  ps.boundsMax = glm::dvec3(0.05);
  ps.samples = 4096;
  ps.bounces = 2;
  ProbeGrid g = bake::bakeProbes(s, t.perMeshLowerOrder, ps);
  ASSERT_EQ(g.probeCount(), 1u);
  ASSERT_TRUE(g.hasDirect());
  ASSERT_EQ(g.direct.size(), g.directStride());
  const sh::ShRgb sky = projectUniform(3, glm::dvec3(1.0));
  const sh::ShRgb none(3);
  // M⁰ · l: relight with everything as "direct" light, minus the full relight, negated.
  const std::vector<glm::vec3> all = relightProbes(g, sky);            // M l
  const std::vector<glm::vec3> bounced = relightProbes(g, none, sky);  // (M − M⁰) l
  const double omega = 2.0 * prt::kPi * (1.0 - std::cos(alpha));
  const double c00 = 0.28209479 * omega, c1y = 0.48860251 * prt::kPi * std::sin(alpha) * std::sin(alpha);
  // 4096 Sobol directions: the opening's share to ~0.3% (ProbeCavity); 1.5% as there.
  EXPECT_NEAR(all[0].g - bounced[0].g, c00, 0.015 * c00);
  EXPECT_NEAR(all[1].g - bounced[1].g, c1y, 0.015 * c1y);
  EXPECT_GT(bounced[0].g, 0.05 * c00);  // the walls do send light with two bounces
  // Against the matrices: c_j = Σ_i M_ji (l_i + d_i) − Σ_i M⁰_ji d_i with M⁰ from the triangle.
  sh::ShRgb l(3), d(3);
  for (int i = 0; i < 9; ++i) {
    l.c[size_t(i)] = glm::vec3(0.1f * i, 0.2f, -0.05f * i);
    d.c[size_t(i)] = glm::vec3(0.3f - 0.02f * i, 0.07f * i, 0.5f);
  }
  const std::vector<glm::vec3> split = relightProbes(g, l, d);
  auto m0 = [&](int j, int i) {
    if (j > i) std::swap(i, j);
    size_t k = 0;
    for (int r = 0; r < j; ++r) k += size_t(9 - r);
    return g.direct[k + size_t(i - j)];
  };
  for (int j = 0; j < 9; ++j) {
    glm::dvec3 expect(0.0);
    for (int i = 0; i < 9; ++i) {
      const float* rgb = &g.transfer[(size_t(j) * 9 + i) * 3];
      expect += glm::dvec3(rgb[0], rgb[1], rgb[2]) * glm::dvec3(l.c[size_t(i)] + d.c[size_t(i)]) -
                double(m0(j, i)) * glm::dvec3(d.c[size_t(i)]);
    }
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(split[size_t(j)][c], expect[c], 1e-4) << j;
  }
}

// The direct part goes through the .vdb and back bit for bit (float32), version 3; a grid
// without it is written as version 2 and read back without it.
// The sky's detail beyond the band limit (DirectBounce::skyDetail, docs/lights.md "Sky
// detail") on an open plane, whose exact direct sky is known: a uniform sky of 1 and a cap of
// 5° at 6° elevation of radiance (200, 100, 50) give E = π + L_cap · π sin²5° · sin 6° (a cap
// above the horizon). Through 3 bands the plane sees the low cap with the clamped cosine's
// 3-band lobe, 0.151 instead of 0.105 at the cap's centre: 6% too bright in red. t⁰ · sh + Δ
// must agree with E on average over the 441 vertices within 1.5%: the cap catches 0.08% of the
// 4096 cosine-weighted rays, 3.4 a vertex, so the mean over vertices has a noise of about
// 0.4% (4σ). A sky that SH holds exactly (uniform) has no detail, and Δ does not depend on
// the thread count.
TEST(BakeSkyDetail, OpenPlaneGetsTheSkyBeyondTheBandLimit) {
  Scene s = test::makeScene({test::makePlane({0.0f, 0.0f, 0.0f}, 2.0f, 20)}, 0.8f);
  bake::BakeSettings bs;
  bs.samples = 256;
  bs.bounces = 1;
  bs.seed = 3;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  const glm::dvec3 capDir = azimuthElevationDirection(40.0, 6.0), capL(200.0, 100.0, 50.0);
  const double capRadius = glm::radians(5.0);
  RigBackground sky;
  sky.uniform = glm::dvec3(1.0);
  sky.caps.push_back({capDir, std::cos(capRadius), capL});
  sh::ShRgb l = projectUniform(3, glm::dvec3(1.0));
  l += projectDiskRadiance(3, capDir, capRadius, capL);
  const glm::dvec3 exact = glm::dvec3(prt::kPi) + capL * (prt::kPi * std::pow(std::sin(capRadius), 2) * capDir.y);
  bake::BounceSettings b;
  b.samples = 4096;
  b.bounces = bs.bounces;
  b.seed = bs.seed;
  b.threads = 2;
  const bake::DirectBounce rays(s, b);
  const bake::DirectIrradiance delta = rays.skyDetail(sky, l);
  const MeshInstance& m = s.meshes[0];
  ASSERT_EQ(delta.front[0].size(), m.vertexCount());
  glm::dvec3 withDetail(0.0), shOnly(0.0);
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    const float* t0 = m.directTransferOf(v, 3, false);
    glm::dvec3 e(0.0);
    for (int i = 0; i < 9; ++i) e += double(t0[i]) * glm::dvec3(l.c[size_t(i)]);
    shOnly += e / exact;
    withDetail += (e + glm::dvec3(delta.front[0][v])) / exact;
  }
  withDetail /= double(m.vertexCount());
  shOnly /= double(m.vertexCount());
  std::printf(
      "[ measured ] mean E / exact over %zu vertices: through SH (%.4f, %.4f, %.4f), with the sky detail "
      "(%.4f, %.4f, %.4f)\n",
      m.vertexCount(), shOnly.r, shOnly.g, shOnly.b, withDetail.r, withDetail.g, withDetail.b);
  EXPECT_GT(shOnly.r, 1.04);  // the band limit this corrects
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(withDetail[c], 1.0, 0.015) << "channel " << c;

  b.threads = 1;
  const bake::DirectBounce oneThread(s, b);
  EXPECT_EQ(oneThread.skyDetail(sky, l).front, delta.front);

  // A map that SH holds exactly (bands 0 and 1, turned 70° about a tilted axis) has no detail
  // either: the map is read the way it is projected (orientation, rotation, scale); what is
  // left is the pixels' bilinear reading against their projection, ~1e-3 of E at 128 × 64.
  {
    ImageRgb map(128, 64);
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 128; ++x) {
        const glm::dvec3 d = equirectDirection((x + 0.5) / 128.0, (y + 0.5) / 64.0);
        map.at(x, y) = glm::vec3(float(1.0 + 0.5 * d.x + 0.3 * d.z - 0.2 * d.y));
      }
    const glm::dmat3 rotation = sh::rotationAxis(glm::normalize(glm::dvec3(0.3, 1.0, 0.2)), 70.0);
    RigBackground turned;
    turned.maps.push_back({std::make_shared<const ImageRgb>(map), glm::transpose(rotation), glm::dvec3(2.0)});
    sh::ShRgb lm = sh::Rotation(3, rotation).apply(projectEnvironment(map, 3));
    lm *= glm::vec3(2.0f);
    const bake::DirectIrradiance flat = rays.skyDetail(turned, lm);
    double worstMap = 0.0;
    for (const glm::vec3& d : flat.front[0]) worstMap = std::max(worstMap, double(glm::length(d)));
    std::printf("[ measured ] detail of a band-1 map, turned: worst %.3g (E about %.3g)\n", worstMap, 2.0 * prt::kPi);
    EXPECT_LT(worstMap, 5e-3 * 2.0 * prt::kPi);
  }

  RigBackground uniform;
  uniform.uniform = glm::dvec3(0.7, 0.5, 0.3);
  const bake::DirectIrradiance none = rays.skyDetail(uniform, projectUniform(3, uniform.uniform));
  double worst = 0.0;
  for (const glm::vec3& d : none.front[0]) worst = std::max({worst, double(std::fabs(d.r)), double(std::fabs(d.g))});
  EXPECT_LT(worst, 1e-5);
}

TEST(ProbeDirect, VdbRoundTripKeepsTheDirectPart) {
  Scene s = test::makeScene({test::makeSlab({-1, -1, -1}, {1, -0.8f, 1})}, 0.5f);
  bake::ProbeSettings ps;
  ps.dims = glm::ivec3(2, 2, 2);
  ps.boundsMin = glm::dvec3(-0.5, -0.5, -0.5);
  ps.boundsMax = glm::dvec3(0.5, 0.5, 0.5);
  ps.samples = 256;
  const ProbeGrid g = bake::bakeProbes(s, {}, ps);
  ASSERT_TRUE(g.hasDirect());
  test::TempDir d;
  writeProbeGrid(g, d.file("p.vdb"));
  const ProbeGrid back = readProbeGrid(d.file("p.vdb"));
  ASSERT_EQ(back.direct.size(), g.direct.size());
  // Both sorted by coordinate (the bake's lattice order is x fastest, the reader's z fastest).
  for (size_t p = 0; p < g.probeCount(); ++p) {
    const int q = back.find(g.coord[p]);
    ASSERT_GE(q, 0);
    EXPECT_EQ(0, std::memcmp(&g.direct[p * g.directStride()], &back.direct[size_t(q) * g.directStride()],
                             g.directStride() * sizeof(float)));
  }
  EXPECT_NE(describeProbeFile(d.file("p.vdb")).find("direct_00_00 .. direct_08_08 (45 float grids"), std::string::npos)
      << describeProbeFile(d.file("p.vdb"));
  ProbeGrid old = g;
  old.direct.clear();
  writeProbeGrid(old, d.file("old.vdb"));
  EXPECT_FALSE(readProbeGrid(d.file("old.vdb")).hasDirect());
  EXPECT_NE(describeProbeFile(d.file("old.vdb")).find("v2"), std::string::npos);
}

// The rig sends suns and disks up to kMaxDirectRadiusDegrees to `direct`, with their SH in
// directSh; maps, uniform skies and wide disks stay in sh; the sum is evaluate().
TEST(RigDirect, SmallSourcesAreDirectAndTheSumIsUnchanged) {
  LightRig rig;
  RigLight sun, wide, sky;
  sun.type = RigLight::Type::Sun;
  sun.direction = Track::constant(glm::dvec3(0.3, 1.0, 0.2));
  sun.direction.direction = true;
  sun.color = Track::constant(glm::dvec3(3.0, 2.0, 1.0));
  wide.type = RigLight::Type::Disk;
  wide.radius = Track::constant(40.0);
  wide.color = Track::constant(0.5);
  sky.type = RigLight::Type::Uniform;
  sky.color = Track::constant(0.2);
  rig.lights = {sun, wide, sky};
  rig.window = sh::Window::Hann;
  rig.validate();
  const RigLighting l = rig.evaluateLighting(0.0, 3);
  ASSERT_EQ(l.direct.size(), 1u);
  EXPECT_NEAR(glm::length(l.direct[0].direction - glm::normalize(glm::dvec3(0.3, 1.0, 0.2))), 0.0, 1e-12);
  EXPECT_EQ(l.direct[0].irradiance, glm::dvec3(3.0, 2.0, 1.0));
  const sh::ShRgb sum = rig.evaluate(0.0, 3);
  for (int i = 0; i < 9; ++i)
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(l.sh.c[size_t(i)][c] + l.directSh.c[size_t(i)][c], sum.c[size_t(i)][c], 1e-5);
}

}  // namespace
}  // namespace prt

namespace prt {
namespace {

// A map holding a uniform sky and a bright disk: the rig splits the disk off as a direct light
// that turns with the map (its direction is R d), the residual goes through sh, and sh + directSh
// equals the map's projection to the cap model's accuracy (bands 0 and 1 exactly: the cap keeps
// the excess's power and its vector irradiance; 1e-3 of l_00 covers float sums). extract_sun
// false (or --no-extract-sun) leaves the map whole.
TEST(RigDirect, MapSunIsSplitOffAndTurnsWithTheMap) {
  ImageRgb map(256, 128);
  const glm::dvec3 sunDir = glm::normalize(glm::dvec3(1.0, 1.0, 0.0));  // 45° up towards +X
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      const glm::dvec3 d = equirectDirection((x + 0.5) / map.width, (y + 0.5) / map.height);
      map.at(x, y) =
          glm::vec3(0.5f) + (glm::dot(d, sunDir) > std::cos(glm::radians(3.0)) ? glm::vec3(2000.0f) : glm::vec3(0.0f));
    }
  LightRig rig;
  RigLight env;
  env.type = RigLight::Type::Environment;
  env.file = "sky.exr";
  env.rotation = Track::constant(90.0);  // light from +X comes from −Z
  rig.lights = {env};
  rig.provideMap("sky.exr", map);
  rig.validate();
  const RigLighting l = rig.evaluateLighting(0.0, 3);
  ASSERT_EQ(l.direct.size(), 1u);
  const glm::dvec3 turned = glm::normalize(glm::dvec3(0.0, 1.0, -1.0));
  EXPECT_LT(glm::degrees(std::acos(std::min(1.0, glm::dot(l.direct[0].direction, turned)))), 0.5);
  EXPECT_GT(l.mapShare[0], 0.5);
  const sh::ShRgb whole = rig.evaluate(0.0, 3);
  for (int i = 0; i < 4; ++i)
    EXPECT_NEAR(l.sh.c[size_t(i)].g + l.directSh.c[size_t(i)].g, whole.c[size_t(i)].g, 1e-3 * whole.c[0].g) << i;
  rig.lights[0].extractSun = false;
  EXPECT_TRUE(rig.evaluateLighting(0.0, 3).direct.empty());
}

}  // namespace
}  // namespace prt
