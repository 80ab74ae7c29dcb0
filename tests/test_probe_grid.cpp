// Probe grid (prt/probe_grid.h): index, relighting, interpolation with leak prevention, and the
// OpenVDB file (round trip, readable by vdb_print and pyopenvdb, clean errors on bad files).
// Analytic cases first: an empty scene must give back the light, a linear field must be
// reproduced exactly by trilinear weights, a wall must stop light.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "harness.h"
#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/math.h"
#include "prt/probe_grid.h"
#include "prt/sh.h"
#include "test_util.h"

namespace prt {
namespace {

namespace fs = std::filesystem;

constexpr const char* kPython = "/usr/bin/python3";  // Debian's: the one with pyopenvdb
constexpr const char* kVdbPrint = "/usr/bin/vdb_print";

float* transferOf(ProbeGrid& g, size_t p) { return g.transfer.data() + p * g.transferStride(); }

sh::ShRgb randomLight(int bands, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  sh::ShRgb l(bands);
  for (auto& c : l.c) c = glm::vec3(u(rng), u(rng), u(rng));
  return l;
}

glm::vec3 randomDir(std::mt19937& rng) {
  std::normal_distribution<float> g;
  glm::vec3 d;
  do d = glm::vec3(g(rng), g(rng), g(rng));
  while (glm::length(d) < 1e-3f);
  return glm::normalize(d);
}

glm::vec3 randomPointInside(const ProbeGrid& g, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  glm::dvec3 t(u(rng), u(rng), u(rng));
  return glm::vec3(g.origin + g.spacing * glm::dvec3(g.dims - 1) * t);
}

float sumWeights(const ProbeWeights& w) {
  float s = 0.0f;
  for (int k = 0; k < w.count; ++k) s += w.weight[size_t(k)];
  return s;
}

// Total normalised weight that the probes with lattice x-index `ix` get.
float weightOfColumn(const ProbeGrid& g, const ProbeWeights& w, int ix) {
  float s = 0.0f;
  for (int k = 0; k < w.count; ++k)
    if (g.coord[size_t(w.probe[size_t(k)])].x == ix) s += w.weight[size_t(k)];
  return s;
}

using test::TempDir;

bool havePyopenvdb() { return fs::exists(kPython) && test::run(kPython, {"-c", "import pyopenvdb"}).status == 0; }

void writeText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// Asserts that f throws prt::Error and that its message names `path` and contains `what`.
template <class F>
void expectError(F&& f, const std::string& path, const std::string& what) {
  try {
    f();
    ADD_FAILURE() << "no prt::Error for " << path << " (expected '" << what << "')";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << msg;
  }
}

// ---- Faces and index

TEST(ProbeGridFace, DominantAxisAndSign) {
  EXPECT_EQ(faceOf({1.0f, 0.5f, -0.2f}), int(Face::PosX));
  EXPECT_EQ(faceOf({-2.0f, 1.0f, 1.0f}), int(Face::NegX));
  EXPECT_EQ(faceOf({0.1f, 3.0f, 2.0f}), int(Face::PosY));
  EXPECT_EQ(faceOf({0.1f, -3.0f, 2.0f}), int(Face::NegY));
  EXPECT_EQ(faceOf({0.0f, 0.0f, 1.0f}), int(Face::PosZ));
  EXPECT_EQ(faceOf({0.3f, -0.2f, -1.0f}), int(Face::NegZ));
  // Ties go to the earlier axis, so every direction has exactly one face.
  EXPECT_EQ(faceOf({1.0f, 1.0f, 0.0f}), int(Face::PosX));
  EXPECT_EQ(faceOf({0.0f, -1.0f, 1.0f}), int(Face::NegY));
}

TEST(ProbeGridIndex, FindsActiveProbesOnly) {
  ProbeGrid g;
  g.bands = 1;
  g.dims = {3, 2, 4};
  // Active probes in no particular order; (1, 1, 1) and others stay inactive.
  g.coord = {{2, 1, 3}, {0, 0, 0}, {1, 0, 2}, {2, 0, 0}, {0, 1, 3}};
  g.buildIndex();
  for (size_t p = 0; p < g.coord.size(); ++p) EXPECT_EQ(g.find(g.coord[p]), int(p));
  EXPECT_EQ(g.find({1, 1, 1}), -1);
  EXPECT_EQ(g.find({0, 0, 1}), -1);
  EXPECT_EQ(g.find({3, 0, 0}), -1);  // outside dims
  EXPECT_EQ(g.find({-1, 0, 0}), -1);
  EXPECT_EQ(g.find({0, 2, 0}), -1);
  EXPECT_EQ(g.find({0, 0, 4}), -1);
}

// ---- Relighting

TEST(ProbeGridRelight, IdentityTransferGivesTheLight) {
  std::mt19937 rng(1);
  const ProbeGrid g = test::identityProbeGrid(3, {2, 2, 2}, glm::dvec3(0.0), glm::dvec3(1.0));
  const sh::ShRgb light = randomLight(3, rng);
  const std::vector<glm::vec3> c = relightProbes(g, light);
  ASSERT_EQ(c.size(), g.probeCount() * 9);
  // M = I: each c_j is one product l_j · 1 plus zeros, exact in float.
  for (size_t p = 0; p < g.probeCount(); ++p)
    for (int j = 0; j < 9; ++j) EXPECT_EQ(c[p * 9 + size_t(j)], light.c[size_t(j)]);
}

TEST(ProbeGridRelight, MatchesDirectMatrixProduct) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  ProbeGrid g = test::identityProbeGrid(3, {3, 2, 2}, glm::dvec3(0.0), glm::dvec3(1.0));
  for (float& v : g.transfer) v = u(rng);
  // More bands in the light than in the grid (truncated) and fewer (zero-padded).
  for (int lightBands : {4, 2}) {
    const sh::ShRgb light = randomLight(lightBands, rng);
    const std::vector<glm::vec3> c = relightProbes(g, light);
    for (size_t p = 0; p < g.probeCount(); ++p)
      for (int j = 0; j < 9; ++j)
        for (int ch = 0; ch < 3; ++ch) {
          double expected = 0.0;
          for (int i = 0; i < std::min(9, light.size()); ++i)
            expected += double(transferOf(g, p)[(j * 9 + i) * 3 + ch]) * light.c[size_t(i)][ch];
          // 9 float products of magnitude <= 1 summed in float: rounding < 9 · 2⁻²⁴ · 9 ≈ 5e-6.
          EXPECT_NEAR(c[p * 9 + size_t(j)][ch], expected, 1e-5) << "probe " << p << " j " << j;
        }
  }
}

// ---- Interpolation

TEST(ProbeGridInterpolate, EmptySceneGivesTheLightEverywhere) {
  std::mt19937 rng(3);
  const ProbeGrid g = test::identityProbeGrid(3, {4, 3, 5}, glm::dvec3(-1.0, 0.5, 2.0), glm::dvec3(0.5, 0.7, 0.6));
  const sh::ShRgb light = randomLight(3, rng);
  const std::vector<glm::vec3> relit = relightProbes(g, light);
  for (int k = 0; k < 200; ++k) {
    const glm::vec3 x = randomPointInside(g, rng);
    const glm::vec3 n = randomDir(rng);
    for (const glm::vec3* normal : {static_cast<const glm::vec3*>(nullptr), &n}) {
      const sh::ShRgb c = interpolateRadiance(g, relit, x, normal);
      ASSERT_EQ(c.bands, 3);
      // Every probe holds exactly l; the weights sum to 1 up to float rounding (~1e-7), so
      // the result is l to a few ulps.
      for (int i = 0; i < 9; ++i)
        for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(c.c[size_t(i)][ch], light.c[size_t(i)][ch], 1e-6f);
      // A receiver in empty space gets the irradiance of an unoccluded surface.
      const glm::vec3 e = sh::irradiance(c, n), e0 = sh::irradiance(light, n);
      for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(e[ch], e0[ch], 1e-5f);
    }
  }
  // A uniform white sky of radiance 1 (l_0 = 2√π) gives E = π at any normal.
  sh::ShRgb sky(3);
  sky.c[0] = glm::vec3(float(2.0 * std::sqrt(prt::kPi)));
  const std::vector<glm::vec3> relitSky = relightProbes(g, sky);
  const glm::vec3 n = randomDir(rng);
  const glm::vec3 e = sh::irradiance(interpolateRadiance(g, relitSky, randomPointInside(g, rng), &n), n);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(e[ch], float(prt::kPi), 1e-5f);
}

TEST(ProbeGridInterpolate, TrilinearReproducesLinearField) {
  std::mt19937 rng(4);
  ProbeGrid g = test::identityProbeGrid(2, {4, 3, 3}, glm::dvec3(1.0, -2.0, 0.5), glm::dvec3(0.8, 0.8, 0.8));
  auto a = [](const glm::dvec3& p) { return 1.0 + 0.2 * p.x - 0.15 * p.y + 0.1 * p.z; };
  const int n2 = g.coeffs();
  for (size_t p = 0; p < g.probeCount(); ++p)
    for (int j = 0; j < n2; ++j)
      for (int c = 0; c < 3; ++c) transferOf(g, p)[(j * n2 + j) * 3 + c] = float(a(g.position(p)));
  const sh::ShRgb light = randomLight(2, rng);
  const std::vector<glm::vec3> relit = relightProbes(g, light);
  for (int k = 0; k < 300; ++k) {
    const glm::vec3 x = randomPointInside(g, rng);
    const sh::ShRgb c = interpolateRadiance(g, relit, x, nullptr);
    const double ax = a(glm::dvec3(x));
    // Trilinear interpolation reproduces linear functions exactly; what remains is float
    // rounding of a ≈ 1, the weights and 8 products (≈ 1e-6).
    for (int i = 0; i < n2; ++i)
      for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(c.c[size_t(i)][ch], ax * light.c[size_t(i)][ch], 1e-5);
  }
}

// Two layers of probes at x = 0 and x = 1 with a wall at x = 0.5 between them: the faces that
// look through the wall (+X of the left probes, −X of the right ones) see it at depth 0.5 along x
// with a spread σ = 0.01; every other face sees nothing within the miss distance.
ProbeGrid wallGrid(bool withWall) {
  ProbeGrid g = test::identityProbeGrid(2, {2, 2, 2}, glm::dvec3(0.0), glm::dvec3(1.0));
  for (size_t p = 0; p < g.probeCount(); ++p) {
    const bool left = g.coord[p].x == 0;
    // The left room is lit (M = I), the right one dark (M = 0).
    if (!left) std::fill_n(transferOf(g, p), g.transferStride(), 0.0f);
    if (withWall) g.moments[p][size_t(left ? Face::PosX : Face::NegX)] = glm::vec2(0.5f, 0.5f * 0.5f + 1e-4f);
  }
  return g;
}

TEST(ProbeGridInterpolate, WallStopsLightFromTheOtherSide) {
  const ProbeGrid walled = wallGrid(true), open = wallGrid(false);
  const glm::vec3 nRight(1.0f, 0.0f, 0.0f);  // the right face of the wall
  sh::ShRgb light(2);
  light.c[0] = glm::vec3(1.0f);
  const std::vector<glm::vec3> relit = relightProbes(walled, light);
  for (const glm::vec3& x :
       {glm::vec3(0.6f, 0.5f, 0.5f), glm::vec3(0.55f, 0.46f, 0.53f), glm::vec3(0.7f, 0.45f, 0.55f)}) {
    // Plain trilinear gives the left probes 1 − x: a large share of light through the wall.
    const ProbeWeights plain = probeWeights(open, x, nullptr);
    EXPECT_NEAR(weightOfColumn(open, plain, 0), 1.0f - x.x, 1e-6f);
    for (const glm::vec3* normal : {static_cast<const glm::vec3*>(nullptr), &nRight}) {
      const ProbeWeights w = probeWeights(walled, x, normal);
      EXPECT_NEAR(sumWeights(w), 1.0f, 1e-6f);
      // The left probes keep (σ²/(σ² + (|d_x| − μ)²))³ of their trilinear weight, σ = 0.01:
      // 5.6e-5 at 0.05 behind the wall, ~1e-6 (the floor) from 0.1 on; less the back-face
      // weight with the normal. Their share of the total is below 1e-4 at every point here.
      EXPECT_LT(weightOfColumn(walled, w, 0), 1e-4f) << x.x;
      EXPECT_LT(interpolateRadiance(walled, relit, x, normal).c[0].x, 1e-4f);
    }
  }
  // And symmetrically: a receiver just left of the wall sees the lit room only.
  const ProbeWeights w = probeWeights(walled, glm::vec3(0.45f, 0.5f, 0.5f), nullptr);
  EXPECT_GT(weightOfColumn(walled, w, 0), 1.0f - 1e-4f);
}

// Moments as the bake measures them for the wall x = 0.5: per face, the mean and mean square of
// the first hit's depth along the face's axis over a Fibonacci sphere of directions, misses at
// 2 × spacing.
ProbeGrid bakedWallGrid() {
  ProbeGrid g = wallGrid(false);
  const int n = 4096;
  const float miss = 2.0f;
  for (size_t p = 0; p < g.probeCount(); ++p) {
    const glm::vec3 P = glm::vec3(g.position(p));
    std::array<glm::dvec3, 6> acc{};  // sum d, sum d², count
    for (int k = 0; k < n; ++k) {
      const double z = 1.0 - (2.0 * k + 1.0) / n, rho = std::sqrt(1.0 - z * z);
      const double phi = k * prt::kPi * (3.0 - std::sqrt(5.0));
      const glm::vec3 w(float(rho * std::cos(phi)), float(rho * std::sin(phi)), float(z));
      const int f = faceOf(w);
      float t = std::numeric_limits<float>::infinity();
      if ((0.5f - P.x) * w.x > 0.0f) t = (0.5f - P.x) / w.x;
      const float d = std::min(miss, t * std::fabs(w[f / 2]));
      acc[size_t(f)] += glm::dvec3(d, double(d) * d, 1.0);
    }
    for (int f = 0; f < 6; ++f)
      g.moments[p][size_t(f)] =
          glm::vec2(float(acc[size_t(f)].x / acc[size_t(f)].z), float(acc[size_t(f)].y / acc[size_t(f)].z));
  }
  return g;
}

// The same wall with moments as the bake measures them. With depths along the axis, every ray of
// the +X face of a left probe sees the wall at depth 0.5 (σ² only float rounding, floored at
// 0.01²), so behind it the weight falls as (0.01² / (0.01² + δ²))³: 1e-6 at δ = 0.1. Ray
// lengths (version 1) spread over 0.5 .. 0.87 (μ ≈ 0.61, σ ≈ 0.08) and let receivers within
// ~0.1 behind the wall pass. Measured shares of the lit probes (averaged over y, z; the v1 row
// with the version-1 interpolation, dominant face only):
//   x                   0.501  0.6    0.75   0.9
//   plain trilinear     0.50   0.40   0.25   0.10
//   ray length (v1)     0.50   0.22   0.039  0.0023
//   axis depth (v2)     0.49   6.7e-7 3.3e-7 1.1e-7
// A wall of zero thickness cannot separate a receiver 0.001 behind it (less than σ): there only
// the back-face weight helps (0.2 of the weight kept, share 0.19). Real walls have a thickness;
// the baked two-room test in test_probe_bake.cpp measures those.
TEST(ProbeGridInterpolate, BakedWallMomentsCutTheLeakBehindTheWall) {
  const ProbeGrid baked = bakedWallGrid(), open = wallGrid(false);
  EXPECT_NEAR(baked.moments[0][size_t(Face::PosX)].x, 0.5f, 1e-6f);
  auto meanShare = [](const ProbeGrid& g, float x0, const glm::vec3* normal) {
    std::mt19937 rng(12);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    double s = 0.0;
    const int m = 1000;
    for (int k = 0; k < m; ++k) {
      const glm::vec3 x(x0, u(rng), u(rng));
      s += weightOfColumn(g, probeWeights(g, x, normal), 0);
    }
    return s / m;
  };
  EXPECT_NEAR(meanShare(open, 0.75f, nullptr), 0.25, 1e-6);
  // Bounds an order of magnitude above the measured shares; ray lengths would fail the first.
  EXPECT_LT(meanShare(baked, 0.6f, nullptr), 1e-5);
  EXPECT_LT(meanShare(baked, 0.75f, nullptr), 1e-5);
  EXPECT_LT(meanShare(baked, 0.9f, nullptr), 1e-5);
  const glm::vec3 n(1.0f, 0.0f, 0.0f);
  EXPECT_LT(meanShare(baked, 0.501f, &n), 0.25);
  EXPECT_LT(meanShare(baked, 0.6f, &n), 1e-5);
}

TEST(ProbeGridInterpolate, EveryProbeBlockedFallsBackToTrilinear) {
  ProbeGrid g = test::identityProbeGrid(1, {2, 2, 2}, glm::dvec3(0.0), glm::dvec3(1.0));
  std::array<glm::vec2, 6> m;
  m.fill(glm::vec2(0.01f, 0.01f * 0.01f));  // geometry right around every probe
  g.moments.assign(g.probeCount(), m);
  const glm::vec3 x(0.3f, 0.6f, 0.8f);
  const ProbeWeights w = probeWeights(g, x, nullptr);
  ASSERT_EQ(w.count, 8);
  for (int k = 0; k < 8; ++k) {
    const glm::ivec3 c = g.coord[size_t(w.probe[size_t(k)])];
    const float wt = (c.x ? x.x : 1 - x.x) * (c.y ? x.y : 1 - x.y) * (c.z ? x.z : 1 - x.z);
    // Each weight is wt · 1e-6 (clamped), then normalised: exactly trilinear up to rounding.
    EXPECT_NEAR(w.weight[size_t(k)], wt, 1e-6f);
  }
}

TEST(ProbeGridInterpolate, InvalidProbesAreNeverRead) {
  ProbeGrid g = test::identityProbeGrid(2, {3, 3, 3}, glm::dvec3(0.0), glm::dvec3(1.0));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  // Probe (1, 1, 1) is inside geometry: its data is garbage that would poison any sum.
  const int bad = g.find({1, 1, 1});
  g.validity[size_t(bad)] = 0.0f;
  std::fill_n(transferOf(g, size_t(bad)), g.transferStride(), nan);
  g.moments[size_t(bad)].fill(glm::vec2(nan));
  sh::ShRgb light(2);
  light.c[0] = glm::vec3(1.0f, 2.0f, 3.0f);
  const std::vector<glm::vec3> relit = relightProbes(g, light);
  const glm::vec3 n(0.0f, 1.0f, 0.0f);
  // Near it (it would be the nearest probe, trilinear weight 0.86) and exactly on it (all the
  // trilinear weight is its own: the valid neighbours of the cell take over).
  for (const glm::vec3& x : {glm::vec3(1.05f, 0.95f, 1.02f), glm::vec3(1.0f), glm::vec3(1.5f, 1.0f, 1.0f)}) {
    const ProbeWeights w = probeWeights(g, x, &n);
    ASSERT_GT(w.count, 0);
    for (int k = 0; k < w.count; ++k) EXPECT_NE(w.probe[size_t(k)], bad);
    EXPECT_NEAR(sumWeights(w), 1.0f, 1e-6f);
    const sh::ShRgb c = interpolateRadiance(g, relit, x, &n);
    EXPECT_NEAR(c.c[0].z, 3.0f, 1e-5f);  // all valid probes hold the light exactly
  }
  // A cell whose probes are all invalid gives nothing.
  ProbeGrid allBad = test::identityProbeGrid(1, {2, 2, 2}, glm::dvec3(0.0), glm::dvec3(1.0));
  allBad.validity.assign(allBad.probeCount(), 0.0f);
  EXPECT_EQ(probeWeights(allBad, glm::vec3(0.5f), nullptr).count, 0);
}

// The domain is the lattice's box grown by half a spacing (the probes' cells): within it every
// point gets probes; up to one spacing beyond it too, with a fade (cover Fade); farther, no
// probe applies (count 0, cover Outside).
TEST(ProbeGridInterpolate, BeyondTheDomainFadesThenGivesNothing) {
  const ProbeGrid g = test::identityProbeGrid(1, {3, 2, 2}, glm::dvec3(-1.0, 0.0, 2.0), glm::dvec3(0.5));
  const std::vector<glm::vec3> relit = relightProbes(g, sh::ShRgb(1));
  glm::dvec3 lo, hi;
  probeDomain(g, lo, hi);
  EXPECT_EQ(lo, glm::dvec3(-1.25, -0.25, 1.75));
  EXPECT_EQ(hi, glm::dvec3(0.25, 0.75, 2.75));
  for (int a = 0; a < 3; ++a) {
    for (double beyond : {0.01, 0.2, 0.49}) {  // world units; the spacing is 0.5
      glm::vec3 below = glm::vec3(0.5 * (lo + hi)), above = below;
      below[a] = float(lo[a] - beyond);
      above[a] = float(hi[a] + beyond);
      for (const glm::vec3& x : {below, above}) {
        const ProbeWeights w = probeWeights(g, x, nullptr);
        EXPECT_GT(w.count, 0) << a;
        EXPECT_EQ(w.cover, ProbeCover::Fade) << a;
        EXPECT_NEAR(w.fade, beyond / 0.5 - 1e-4, 1e-5) << a;
      }
    }
    glm::vec3 below = glm::vec3(0.5 * (lo + hi)), above = below;
    below[a] = float(lo[a]) - 0.51f;
    above[a] = float(hi[a]) + 0.51f;
    EXPECT_EQ(probeWeights(g, below, nullptr).count, 0) << a;
    EXPECT_EQ(probeWeights(g, below, nullptr).cover, ProbeCover::Outside) << a;
    EXPECT_EQ(probeWeights(g, above, nullptr).count, 0) << a;
    EXPECT_EQ(interpolateRadiance(g, relit, above, nullptr).c[0], glm::vec3(0.0f));
  }
  // The domain's box itself is inside, corners included, without a fade.
  EXPECT_GT(probeWeights(g, glm::vec3(lo), nullptr).count, 0);
  EXPECT_EQ(probeWeights(g, glm::vec3(lo), nullptr).fade, 0.0f);
  EXPECT_GT(probeWeights(g, glm::vec3(hi), nullptr).count, 0);
  EXPECT_EQ(probeWeights(g, glm::vec3(NAN), nullptr).count, 0);
}

// In the half-cell shell between the lattice's box and the domain's edge the query is clamped
// to the box: a field linear in position takes its value on the box's nearest face (on every
// axis that lies outside), and the cover says Shell; inside the box it says Lattice.
TEST(ProbeGridInterpolate, HalfCellShellClampsToTheNearestProbes) {
  ProbeGrid g = test::identityProbeGrid(1, {3, 3, 2}, glm::dvec3(0.5, 1.0, -1.0), glm::dvec3(1.0, 0.5, 2.0));
  auto field = [](const glm::dvec3& p) { return 1.0 + 0.5 * p.x - 2.0 * p.y + 0.25 * p.z; };
  for (size_t p = 0; p < g.probeCount(); ++p) transferOf(g, p)[0] = float(field(g.latticePosition(g.coord[p])));
  sh::ShRgb white(1);
  white.c[0] = glm::vec3(1.0f);
  const std::vector<glm::vec3> relit = relightProbes(g, white);
  const glm::dvec3 boxLo = g.origin, boxHi = g.origin + g.spacing * glm::dvec3(g.dims - 1);
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> in(0.0, 1.0);
  std::uniform_int_distribution<int> zone(0, 2);
  int shell = 0;
  for (int k = 0; k < 200; ++k) {
    // A point of the domain: per axis in the low shell, the box or the high shell.
    glm::dvec3 x;
    for (int a = 0; a < 3; ++a) {
      const double h = (0.001 + 0.4989 * in(rng)) * g.spacing[a];
      const int z = zone(rng);
      x[a] = z == 0 ? boxLo[a] - h : z == 2 ? boxHi[a] + h : boxLo[a] + (boxHi[a] - boxLo[a]) * in(rng);
    }
    const glm::dvec3 clamped = glm::clamp(x, boxLo, boxHi);
    const ProbeWeights w = probeWeights(g, glm::vec3(x), nullptr);
    ASSERT_GT(w.count, 0) << x.x << " " << x.y << " " << x.z;
    const bool outsideBox = clamped != x;
    shell += outsideBox;
    EXPECT_EQ(w.cover, outsideBox ? ProbeCover::Shell : ProbeCover::Lattice);
    const float v = interpolateRadiance(g, relit, glm::vec3(x), nullptr).c[0].r;
    EXPECT_NEAR(v, field(clamped), 1e-5 * (1.0 + std::fabs(field(clamped))));
  }
  EXPECT_GT(shell, 50);
}

// receiverRadiance: the probes' value where they apply; blended into the light beyond the
// domain; the light itself (M = I) farther out and in a cell whose probes are all invalid, with
// the cover saying why.
TEST(ProbeGridInterpolate, ReceiverRadianceFallsBackToTheUnoccludedLight) {
  ProbeGrid g = test::identityProbeGrid(3, {2, 2, 2}, glm::dvec3(0.0), glm::dvec3(1.0));
  for (float& v : g.transfer) v *= 0.5f;
  std::mt19937 rng(5);
  const sh::ShRgb light = randomLight(3, rng);
  const std::vector<glm::vec3> relit = relightProbes(g, light);
  const glm::vec3 n(0.0f, 1.0f, 0.0f);
  ProbeCover cover;
  sh::ShRgb c = receiverRadiance(g, relit, light, glm::vec3(0.5f, 1.3f, 0.5f), &n, &cover);  // shell
  EXPECT_EQ(cover, ProbeCover::Shell);
  for (int j = 0; j < 9; ++j) EXPECT_NEAR(c.c[size_t(j)].g, 0.5f * light.c[size_t(j)].g, 1e-6f) << j;
  // Beyond the domain's edge y = 1.5: the probes (half the light) fade into the light over one
  // spacing, continuously, share f = (y − 1.5) − 10⁻⁴; from y = 2.5 on, the light itself.
  for (float y : {1.5f, 1.6f, 2.0f, 2.4f, 2.4999f}) {
    c = receiverRadiance(g, relit, light, glm::vec3(0.5f, y, 0.5f), &n, &cover);
    const double f = std::clamp(double(y) - 1.5 - 1e-4, 0.0, 1.0);
    EXPECT_EQ(cover, f > 0.0 ? ProbeCover::Fade : ProbeCover::Shell) << y;
    for (int j = 0; j < 9; ++j)
      EXPECT_NEAR(c.c[size_t(j)].g, ((1.0 - f) * 0.5 + f) * light.c[size_t(j)].g, 1e-6) << y << " " << j;
  }
  c = receiverRadiance(g, relit, light, glm::vec3(0.5f, 2.6f, 0.5f), &n, &cover);  // outside
  EXPECT_EQ(cover, ProbeCover::Outside);
  for (int j = 0; j < 9; ++j) EXPECT_EQ(c.c[size_t(j)], light.c[size_t(j)]) << j;
  EXPECT_STREQ(probeCoverName(ProbeCover::Fade), "fade");
  g.validity.assign(g.probeCount(), 0.0f);
  c = receiverRadiance(g, relit, light, glm::vec3(0.5f), &n, &cover);
  EXPECT_EQ(cover, ProbeCover::NoValidProbe);
  for (int j = 0; j < 9; ++j) EXPECT_EQ(c.c[size_t(j)], light.c[size_t(j)]) << j;
  EXPECT_STREQ(probeCoverName(ProbeCover::NoValidProbe), "no_valid_probe");
}

// ---- OpenVDB file

// A grid with every field random and some probes inactive, in a shuffled order.
ProbeGrid randomGrid(int bands, glm::dvec3 spacing, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), pos(0.0f, 1.0f);
  ProbeGrid g;
  g.bands = bands;
  g.dims = {5, 4, 3};
  g.origin = glm::dvec3(-2.5, 0.125, 3.0);
  g.spacing = spacing;
  g.info = {3, 4096, 0xfedcba9876543210ull, "cornell box.gltf"};
  for (int z = 0; z < g.dims.z; ++z)
    for (int y = 0; y < g.dims.y; ++y)
      for (int x = 0; x < g.dims.x; ++x)
        if ((x + 2 * y + 3 * z) % 4 != 0) g.coord.emplace_back(x, y, z);
  std::shuffle(g.coord.begin(), g.coord.end(), rng);
  const size_t count = g.coord.size();
  g.transfer.resize(count * g.transferStride());
  for (float& v : g.transfer) v = u(rng);
  for (size_t p = 0; p < count; ++p) {
    g.validity.push_back(p % 5 == 0 ? 0.0f : 1.0f);
    g.offset.emplace_back(0.1f * u(rng), 0.1f * u(rng), 0.1f * u(rng));
    g.skyVisibility.push_back(pos(rng));
    std::array<glm::vec2, 6> m;
    for (auto& f : m) {
      const float mean = 3.0f * pos(rng);
      f = glm::vec2(mean, mean * mean + pos(rng));
    }
    g.moments.push_back(m);
  }
  g.buildIndex();
  return g;
}

// Compares `back` (read from a file) with `ref` probe by probe; transfer within `tol(v)`.
template <class Tol>
void expectSameGrid(const ProbeGrid& ref, const ProbeGrid& back, Tol tol) {
  EXPECT_EQ(back.bands, ref.bands);
  EXPECT_EQ(back.dims, ref.dims);
  EXPECT_EQ(back.origin, ref.origin);
  EXPECT_EQ(back.spacing, ref.spacing);
  EXPECT_EQ(back.info.bounces, ref.info.bounces);
  EXPECT_EQ(back.info.samples, ref.info.samples);
  EXPECT_EQ(back.info.seed, ref.info.seed);
  EXPECT_EQ(back.info.scene, ref.info.scene);
  ASSERT_EQ(back.probeCount(), ref.probeCount());
  // Read back sorted by (x, y, z).
  EXPECT_TRUE(std::is_sorted(back.coord.begin(), back.coord.end(), [](const glm::ivec3& a, const glm::ivec3& b) {
    return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z);
  }));
  for (size_t q = 0; q < back.probeCount(); ++q) {
    const int p = ref.find(back.coord[q]);
    ASSERT_GE(p, 0);
    EXPECT_EQ(back.find(back.coord[q]), int(q));
    EXPECT_EQ(back.validity[q], ref.validity[size_t(p)]);
    EXPECT_EQ(back.offset[q], ref.offset[size_t(p)]);    // always 32-bit
    EXPECT_EQ(back.moments[q], ref.moments[size_t(p)]);  // always 32-bit
    EXPECT_NEAR(back.skyVisibility[q], ref.skyVisibility[size_t(p)], tol(ref.skyVisibility[size_t(p)]));
    for (size_t k = 0; k < ref.transferStride(); ++k) {
      const float a = ref.transfer[size_t(p) * ref.transferStride() + k];
      ASSERT_NEAR(back.transfer[q * back.transferStride() + k], a, tol(a)) << "probe " << q << " entry " << k;
    }
  }
}

TEST(ProbeGridVdb, RoundTripFloat32IsExact) {
  TempDir dir;
  std::mt19937 rng(5);
  for (glm::dvec3 spacing : {glm::dvec3(0.25), glm::dvec3(0.5, 0.25, 0.75)}) {  // uniform and not
    const ProbeGrid g = randomGrid(3, spacing, rng);
    const std::string path = dir.file("probes.vdb");
    writeProbeGrid(g, path);
    expectSameGrid(g, readProbeGrid(path), [](float) { return 0.0f; });
  }
  // Nothing but the output is left in the directory (the temporary file was renamed).
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
}

TEST(ProbeGridVdb, RoundTripHalfWithinHalfPrecision) {
  TempDir dir;
  std::mt19937 rng(6);
  const ProbeGrid g = randomGrid(3, glm::dvec3(0.5), rng);
  writeProbeGrid(g, dir.file("f32.vdb"), false);
  writeProbeGrid(g, dir.file("f16.vdb"), true);
  // Half: 11 significant bits, relative rounding ≤ 2⁻¹¹; values below 2⁻¹⁴ are subnormal, with
  // absolute spacing 2⁻²⁴ (rounding ≤ 3e-8).
  expectSameGrid(g, readProbeGrid(dir.file("f16.vdb")), [](float v) { return std::ldexp(std::abs(v), -11) + 1e-7f; });
  EXPECT_LT(fs::file_size(dir.file("f16.vdb")), fs::file_size(dir.file("f32.vdb")));
}

TEST(ProbeGridVdb, BandsOneAndEmptyGrid) {
  TempDir dir;
  std::mt19937 rng(7);
  const ProbeGrid one = randomGrid(1, glm::dvec3(1.0), rng);
  writeProbeGrid(one, dir.file("one.vdb"));
  expectSameGrid(one, readProbeGrid(dir.file("one.vdb")), [](float) { return 0.0f; });
  ProbeGrid none = test::identityProbeGrid(2, {2, 2, 2}, glm::dvec3(0.0), glm::dvec3(1.0));
  none.coord.clear();
  none.transfer.clear();
  none.validity.clear();
  none.offset.clear();
  none.skyVisibility.clear();
  none.moments.clear();
  none.buildIndex();
  writeProbeGrid(none, dir.file("none.vdb"));
  const ProbeGrid back = readProbeGrid(dir.file("none.vdb"));
  EXPECT_EQ(back.probeCount(), 0u);
  EXPECT_EQ(back.dims, none.dims);
}

TEST(ProbeGridVdb, DescribeSummarisesTheFile) {
  TempDir dir;
  std::mt19937 rng(8);
  const ProbeGrid g = randomGrid(3, glm::dvec3(0.5), rng);
  writeProbeGrid(g, dir.file("probes.vdb"));
  const std::string text = describeProbeFile(dir.file("probes.vdb"));
  size_t valid = 0;
  for (float v : g.validity) valid += v > 0.0f;
  for (const std::string& s :
       {dir.file("probes.vdb"), std::string("bands         3"), std::string("5 x 4 x 3"),
        cat(g.probeCount(), " active of 60, ", valid, " valid"),
        std::string("transfer_00_00 .. transfer_08_08 (81 Vec3f grids)"), std::string("validity (float)"),
        std::string("moments_sq_neg (Vec3f)"), std::string("(-2.5, 0.125, 3) .. (-0.5, 1.625, 4)"),
        std::string("seed 18364758544493064720"), std::string("cornell box.gltf")})
    EXPECT_NE(text.find(s), std::string::npos) << "missing '" << s << "' in:\n" << text;
}

TEST(ProbeGridVdb, VdbPrintReadsTheFile) {
  if (!fs::exists(kVdbPrint)) GTEST_SKIP() << kVdbPrint << " not installed";
  TempDir dir;
  std::mt19937 rng(9);
  const std::string path = dir.file("probes.vdb");
  writeProbeGrid(randomGrid(2, glm::dvec3(0.5), rng), path, true);
  const test::RunResult r = test::run(kVdbPrint, {"-l", "-m", path}, {.mergeOutput = true});
  EXPECT_EQ(r.status, 0) << r.out;
  for (const char* name : {"transfer_00_00", "transfer_03_03", "validity", "offset", "sky_visibility",
                           "irradiance_preview", "moments_mean_pos", "moments_sq_neg", "prt_format_version"})
    EXPECT_NE(r.out.find(name), std::string::npos) << name << " not in:\n" << r.out;
}

// pyopenvdb (what Blender and Houdini scripts use) sees the values, the transform, the shared
// topology and the metadata.
TEST(ProbeGridVdb, PyopenvdbReadsTheFile) {
  if (!havePyopenvdb()) GTEST_SKIP() << "pyopenvdb not available for " << kPython;
  TempDir dir;
  ProbeGrid g = test::identityProbeGrid(3, {4, 3, 2}, glm::dvec3(-1.0, 0.5, 2.0), glm::dvec3(0.5, 0.25, 1.0));
  const int p = g.find({1, 2, 0});
  transferOf(g, size_t(p))[(4 * 9 + 0) * 3 + 1] = 0.375f;  // M_40, green
  const std::string path = dir.file("probes.vdb");
  writeProbeGrid(g, path);
  const std::string script = dir.file("read.py");
  writeText(script, R"(import sys
import pyopenvdb as vdb
grids, meta = vdb.readAll(sys.argv[1])
byName = {g.name: g for g in grids}
print('value', byName['transfer_04_00'].getConstAccessor().getValue((1, 2, 0))[1])
print('world', *byName['validity'].transform.indexToWorld((1, 2, 0)))
print('irradiance', byName['irradiance_preview'].getConstAccessor().getValue((0, 0, 0))[0])
print('active', *sorted({g.activeVoxelCount() for g in grids}))
print('grids', len(grids))
print('bands', meta['bands'], 'dims', *meta['dims'], 'seed', meta['seed'])
)");
  const test::RunResult r = test::run(kPython, {script, path}, {.mergeOutput = true});
  ASSERT_EQ(r.status, 0) << r.out;
  std::istringstream in(r.out);
  std::string word;
  double value = 0, wx = 0, wy = 0, wz = 0, irradiance = 0;
  long active = 0, grids = 0;
  in >> word >> value >> word >> wx >> wy >> wz >> word >> irradiance >> word >> active >> word >> grids;
  EXPECT_EQ(value, 0.375);
  // Index (1, 2, 0) is origin + spacing ⊙ (1, 2, 0).
  EXPECT_EQ(wx, -0.5);
  EXPECT_EQ(wy, 1.0);
  EXPECT_EQ(wz, 2.0);
  // Empty scene: irradiance at +Y under a uniform sky of radiance 1 is π (float32 rounding).
  EXPECT_NEAR(irradiance, prt::kPi, 1e-5);
  EXPECT_EQ(active, 24);  // one active count shared by every grid: the same topology
  EXPECT_EQ(grids, 81 + 8);
  EXPECT_NE(r.out.find("bands 3 dims 4 3 2 seed 0"), std::string::npos) << r.out;
}

// ---- Bad files

TEST(ProbeGridVdb, MissingNonVdbAndTruncatedFilesRaiseErrors) {
  TempDir dir;
  const std::string missing = dir.file("missing.vdb");
  expectError([&] { readProbeGrid(missing); }, missing, "no such file");
  expectError([&] { describeProbeFile(missing); }, missing, "no such file");

  const std::string text = dir.file("text.vdb");
  writeText(text, "this is not a VDB file, just text long enough to hold a header\n");
  expectError([&] { readProbeGrid(text); }, text, "not an OpenVDB file");
  writeText(text, "");
  expectError([&] { readProbeGrid(text); }, text, "not an OpenVDB file");

  std::mt19937 rng(10);
  const std::string good = dir.file("good.vdb");
  writeProbeGrid(randomGrid(2, glm::dvec3(0.5), rng), good);
  const std::string bytes = readFile(good);
  // Half the file (the case the brief names) and other cut points: inside the header, the
  // metadata, a grid's topology, its compressed buffers, one byte short.
  const std::string cut = dir.file("cut.vdb");
  for (size_t size : {bytes.size() / 2, size_t(12), size_t(200), bytes.size() / 4, bytes.size() * 3 / 4,
                      bytes.size() - 100, bytes.size() - 1}) {
    writeText(cut, bytes.substr(0, size));
    expectError([&] { readProbeGrid(cut); }, cut, "corrupt or truncated");
    expectError([&] { describeProbeFile(cut); }, cut, "corrupt or truncated");
  }
}

// OpenVDB makes a string or vector as long as a size field says (up to 4 GiB, zero-filled) before
// reading it: a corrupt 18 KB file cost 2.5 GB and 5 s. prt checks every such field against the
// bytes left first (vdb_layout.h), so each corrupt size below is named in the message, where
// OpenVDB itself would have allocated and then reported only the end of the file.
TEST(ProbeGridVdb, SizeFieldsAreCheckedBeforeOpenVdbTrustsThem) {
  TempDir dir;
  std::mt19937 rng(12);
  const std::string good = dir.file("good.vdb");
  writeProbeGrid(randomGrid(2, glm::dvec3(0.5), rng), good);
  const std::string bytes = readFile(good);
  const auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  const auto at = [&](const std::string& needle) {
    const size_t i = bytes.find(needle);
    EXPECT_NE(i, std::string::npos) << "no '" << needle << "' in the file";
    return i == std::string::npos ? size_t(0) : i;
  };
  const auto patched = [&](size_t offset, const std::string& with) {
    std::string b = bytes;
    b.replace(offset, with.size(), with);
    return b;
  };
  // The file's metadata item "scene": its name, its type name "string", then the value's size.
  const size_t scene = at(u32(5) + "scene" + u32(6) + "string");
  // The first grid's descriptor: its name, its type name, an empty instance parent, 3 offsets.
  const std::string firstGrid = u32(14) + "transfer_00_00";
  const size_t descriptor = at(firstGrid);
  uint32_t typeLength = 0;
  std::memcpy(&typeLength, bytes.data() + descriptor + firstGrid.size(), 4);
  const size_t offsets = descriptor + firstGrid.size() + 4 + typeLength + 4;
  int64_t blockPos = 0;  // where the grid's topology ends and its leaves' buffers begin
  std::memcpy(&blockPos, bytes.data() + offsets + 8, 8);
  const auto i64 = [](int64_t v) { return std::string(reinterpret_cast<const char*>(&v), 8); };
  // Its io::DelayedLoadMetadata: name, type, byte count, then the count of leaf entries.
  const size_t delayed = at(u32(17) + "file_delayed_load" + u32(13) + "__delayedload") + 4 + 17 + 4 + 13 + 4;

  const std::pair<std::string, std::string> cases[] = {
      {patched(scene + 19, u32(0x7fffffff)), "metadata 'scene' (string) of 2147483647 bytes at byte"},
      {patched(scene, u32(0xf0000000)), ", name of 4026531840 bytes at byte"},
      {patched(8, u32(221)), "VDB file format version 221 is older than prt reads"},
      {patched(8, u32(225)), "VDB file format version 225 is newer than this OpenVDB reads (224)"},
      {patched(20, std::string(1, '\0')), "a VDB stream without grid offsets"},
      {patched(offsets + 16, std::string(8, '\x7f')), "grid 'transfer_00_00', offsets"},
      {patched(offsets + 8, i64(blockPos - 1)),
       cat("grid 'transfer_00_00', topology ends at byte ", blockPos, ", where the file says ", blockPos - 1)},
      {patched(delayed, u32(0x10000000)), "268435456 leaf entries in a grid of"},
  };
  int n = 0;
  for (const auto& [content, what] : cases) {
    const std::string bad = dir.file(cat("bad_", n++, ".vdb"));
    writeText(bad, content);
    expectError([&] { readProbeGrid(bad); }, bad, what);
    try {
      describeProbeFile(bad);
      ADD_FAILURE() << bad << " was read";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
  }
  // The unpatched file still reads (the walk accepts what OpenVDB writes).
  EXPECT_NO_THROW(readProbeGrid(good));
}

// The walk accepts what OpenVDB itself writes: level sets (inactive values ±background), one or
// two other inactive values, all values, tiles, half floats, an empty grid, a frustum transform,
// many grids in one file. Each file then fails only as "not a prt probe file".
TEST(ProbeGridVdb, WalkAcceptsWhatOpenVdbWrites) {
  if (!havePyopenvdb()) GTEST_SKIP() << "pyopenvdb not available for " << kPython;
  TempDir dir;
  const std::string script = dir.file("variants.py");
  writeText(script, R"(import random, sys
import pyopenvdb as vdb
random.seed(1)
out = sys.argv[1]
grids = []
ls = vdb.createLevelSetSphere(radius=20.0, center=(0, 0, 0), voxelSize=0.5, halfWidth=3.0)
ls.name = 'level_set'
grids.append(ls)
half = vdb.createLevelSetSphere(radius=10.0, center=(5, 0, 0), voxelSize=0.5, halfWidth=3.0)
half.name = 'level_set_half'
half.saveFloatAsHalf = True
grids.append(half)
# Leaves whose inactive values are all 7 (one value), all 7 or 3 (two), or anything (all values).
for name, inactive in (('all_values', None), ('two_inactive', (7.0, 3.0)), ('one_inactive', (7.0,))):
    g = vdb.FloatGrid(background=2.5)
    g.name = name
    g.fill((0, 0, 0), (31, 31, 31), 7.0, False)
    a = g.getAccessor()
    for i in range(2000):
        c = (random.randint(0, 31), random.randint(0, 31), random.randint(0, 31))
        a.setValueOn(c, random.random())
        c = (random.randint(0, 31), random.randint(0, 31), random.randint(0, 31))
        a.setValueOff(c, random.choice(inactive) if inactive else random.random())
    grids.append(g)
v = vdb.Vec3SGrid()
v.name = 'vec3_half'
v.saveFloatAsHalf = True
va = v.getAccessor()
for i in range(2000):
    va.setValueOn((random.randint(-30, 30), random.randint(-30, 30), random.randint(-30, 30)), (1, 2, 3))
grids.append(v)
t = vdb.FloatGrid()
t.name = 'tiles'
t.fill((0, 0, 0), (400, 400, 40), 3.0)
grids.append(t)
e = vdb.FloatGrid()
e.name = 'empty'
grids.append(e)
f = vdb.FloatGrid()
f.name = 'frustum'
f.fill((0, 0, 0), (9, 9, 9), 1.0)
f.transform = vdb.createFrustumTransform(xyzMin=(0, 0, 0), xyzMax=(10, 10, 10), taper=0.5, depth=3.0, voxelSize=1.0)
grids.append(f)
vdb.write(out + '/all.vdb', grids)
for g in grids:
    vdb.write(out + '/' + g.name + '.vdb', [g])
b = vdb.BoolGrid()
b.name = 'bool'
b.getAccessor().setValueOn((1, 2, 3), True)
vdb.write(out + '/bool.grid', [b])
)");
  const test::RunResult r = test::run(kPython, {script, dir.path().string()}, {.mergeOutput = true});
  ASSERT_EQ(r.status, 0) << r.out;
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir.path()))
    if (e.path().extension() == ".vdb") {
      ++files;
      expectError([&] { readProbeGrid(e.path().string()); }, e.path().string(),
                  "metadata 'prt_format_version' missing");
    }
  EXPECT_EQ(files, 10);
  // Bool trees (another leaf layout, whose blocks OpenVDB 10 reads as unchecked as any) are
  // refused by name, not handed to OpenVDB.
  const std::string boolGrid = dir.file("bool.grid");
  expectError([&] { readProbeGrid(boolGrid); }, boolGrid,
              "grid 'bool' is a Tree_bool_5_4_3 grid, which prt does not read");
  // A frustum map names a second map: its name's length is checked as well.
  const std::string frustum = dir.file("frustum.vdb");
  std::string bytes = readFile(frustum);
  const std::string affine = std::string("\x09\0\0\0", 4) + "AffineMap";
  const size_t at = bytes.find(affine);
  ASSERT_NE(at, std::string::npos);
  bytes.replace(at, 4, std::string("\xf0\xff\xff\x7f", 4));
  const std::string bad = dir.file("frustum_bad.grid");
  writeText(bad, bytes);
  expectError([&] { readProbeGrid(bad); }, bad, "frustum's second map type name of 2147483632 bytes");
}

// Files that are valid VDB but not a consistent probe grid, made by editing a good file with
// pyopenvdb (the test itself must not include OpenVDB).
TEST(ProbeGridVdb, InconsistentFilesRaiseErrors) {
  if (!havePyopenvdb()) GTEST_SKIP() << "pyopenvdb not available for " << kPython;
  TempDir dir;
  std::mt19937 rng(11);
  const std::string good = dir.file("good.vdb");
  writeProbeGrid(randomGrid(2, glm::dvec3(0.5), rng), good);
  const std::string script = dir.file("edit.py");
  writeText(script, R"(import sys
import pyopenvdb as vdb
src, dst, mode = sys.argv[1:4]
grids, meta = vdb.readAll(src)
if mode == 'drop':
    grids = [g for g in grids if g.name != 'transfer_03_01']
elif mode == 'dims':
    meta['dims'] = (1, 1, 1)
elif mode == 'huge_dims':
    meta['dims'] = (100000, 100000, 100000)
elif mode == 'bands':
    meta['bands'] = 9
elif mode == 'fewer_bands':
    meta['bands'] = 1
elif mode == 'no_version':
    del meta['prt_format_version']
elif mode == 'version_1':
    meta['prt_format_version'] = 1
elif mode == 'version_3':
    meta['prt_format_version'] = 3
elif mode == 'version_4':
    meta['prt_format_version'] = 4
elif mode == 'spacing':
    meta['spacing'] = (0.5, 0.5, 0.25)
vdb.write(dst, grids=grids, metadata=meta)
)");
  const std::pair<const char*, const char*> cases[] = {
      {"drop", "grid 'transfer_03_01' missing"},
      {"dims", "outside dims"},
      {"huge_dims", "exceed 2^31 lattice points"},
      {"bands", "bands = 9, expected 1..8"},
      {"fewer_bands", "needs 1 transfer grids, the file holds 16"},
      {"no_version", "'prt_format_version' missing"},
      {"version_1", "prt_format_version 1 is no longer read: its moment grids hold ray lengths"},
      {"version_3", "grid 'direct_00_00' missing"},  // version 3 without its direct part
      {"version_4", "prt_format_version 4 is not supported (this prt reads 2 and 3)"},
      {"spacing", "does not match metadata"},
  };
  for (const auto& [mode, what] : cases) {
    const std::string bad = dir.file(cat(mode, ".vdb"));
    const test::RunResult r = test::run(kPython, {script, good, bad, mode}, {.mergeOutput = true});
    ASSERT_EQ(r.status, 0) << r.out;
    expectError([&] { readProbeGrid(bad); }, bad, what);
  }
}

TEST(ProbeGridVdb, WriteIntoMissingDirectoryRaisesError) {
  const ProbeGrid g = test::identityProbeGrid(1, {2, 2, 2}, glm::dvec3(0.0), glm::dvec3(1.0));
  const std::string path = "/nonexistent-prt-dir/probes.vdb";
  expectError([&] { writeProbeGrid(g, path); }, path, "does not exist");
}

}  // namespace
}  // namespace prt
