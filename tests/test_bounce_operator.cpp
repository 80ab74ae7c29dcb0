// The direct-to-indirect operator (prt/bounce_operator.h, prt/bake/bounce_operator.h): against
// the bake's own bounced transfer, its compressed form against the uncompressed one, closed
// forms (a closed box's bounce series, the open spherical cavity under a sun), determinism,
// and its packed bytes refused when truncated, corrupt or of another version.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <sstream>

#include "baked_scene.h"
#include "harness.h"
#include "prt/bake/bounce_operator.h"
#include "prt/bake/direct_light.h"
#include "prt/bake/surface_bake.h"
#include "prt/bounce_operator.h"
#include "prt/light.h"
#include "prt/math.h"
#include "prt/sh.h"
#include "test_scenes.h"

namespace prt {
namespace {

// A baked scene (test::bakeInPlace).
void bakeScene(Scene& s, int samples, int bounces, uint64_t seed) { test::bakeInPlace(s, samples, bounces, seed); }

// E⁰ = t⁰ · l per side, and the bake's bounced part (t − t⁰) · l.
struct ShLit {
  bake::DirectIrradiance e0;
  std::vector<std::vector<glm::vec3>> front, back;
};
ShLit shLit(const Scene& s, const sh::ShRgb& l) {
  ShLit r;
  r.e0.front.resize(s.meshes.size()), r.e0.back.resize(s.meshes.size());
  r.front.resize(s.meshes.size()), r.back.resize(s.meshes.size());
  for (size_t k = 0; k < s.meshes.size(); ++k)
    for (int side = 0; side < 2; ++side) {
      const MeshInstance& m = s.meshes[k];
      const std::vector<glm::vec3>& total = side ? m.transferBack : m.transfer;
      if (total.empty()) continue;
      for (size_t v = 0; v < m.vertexCount(); ++v) {
        const float* t0 = m.directTransferOf(v, 3, side == 1);
        glm::vec3 d(0.0f), all = sh::dot(total.data() + v * 9, l.c.data(), 9);
        for (int i = 0; i < 9; ++i) d += t0[i] * l.c[size_t(i)];
        (side ? r.e0.back[k] : r.e0.front[k]).push_back(d);
        (side ? r.back[k] : r.front[k]).push_back(all - d);
      }
    }
  return r;
}

sh::ShRgb someLight() {
  sh::ShRgb l(3);
  for (int i = 0; i < 9; ++i) l.c[size_t(i)] = glm::vec3(1.0f + 0.1f * i, 0.5f - 0.05f * i, 0.3f + 0.02f * i);
  return l;
}

// Every side's values, in one list (front sides of every instance, then back sides).
std::vector<glm::vec3> flat(const std::vector<std::vector<glm::vec3>>& front,
                            const std::vector<std::vector<glm::vec3>>& back) {
  std::vector<glm::vec3> out;
  for (const auto& f : front) out.insert(out.end(), f.begin(), f.end());
  for (const auto& b : back) out.insert(out.end(), b.begin(), b.end());
  return out;
}

// With clusters of one vertex side and rows that keep every leaf, the operator is the bake's
// bounce operator G itself: fed E⁰ = t⁰ · l it returns the bake's (t − t⁰) · l. What differs is
// rounding: the weights are stored in 16 bits (1/65535 each, a ray's share 1/256 is 256 of
// them), so each entry is off by at most 1/512 of one ray's share, at random; over a row of
// hundreds of entries that is ~1e-4 of the total. 1e-3 leaves room, while a wrong albedo, seed,
// side or bounce count is off by percents (BakeDirectBounce's test measures the same).
TEST(BounceOperator, UncompressedIsTheBakesBouncedTransfer) {
  Scene s = test::makeColouredRoom();
  bakeScene(s, 256, 3, 7);
  bake::OperatorSettings os;
  os.samples = 256;
  os.clusterSize = 1;
  const BounceOperator op = bake::buildBounceOperator(s, os, 3, 7, /*uncompressed=*/true);
  const ShLit lit = shLit(s, someLight());
  bake::OperatorLighting lighting(s, op, false);
  const bake::DirectIrradiance got = lighting.lightFrom(lit.e0, nullptr, nullptr, sh::ShRgb(3));
  const std::vector<glm::vec3> g = flat(got.front, got.back), x = flat(lit.front, lit.back),
                               e = flat(lit.e0.front, lit.e0.back);
  ASSERT_EQ(g.size(), x.size());
  double worst = 0.0, scale = 0.0, bounced = 0.0;
  for (size_t v = 0; v < g.size(); ++v)
    for (int c = 0; c < 3; ++c) {
      worst = std::max(worst, double(std::fabs(g[v][c] - x[v][c])));
      scale = std::max(scale, double(std::fabs(x[v][c] + e[v][c])));
      bounced = std::max(bounced, double(std::fabs(x[v][c])));
    }
  std::printf("[ measured ] uncompressed operator against the bake's bounced transfer: worst %.3g of %.3g\n", worst,
              scale);
  EXPECT_GT(bounced, 0.05 * scale);
  EXPECT_LT(worst, 1e-3 * scale);
}

// Relative error of a against the reference r over the sides where r is at least a tenth of its
// mean: median and p95 of |a − r| / mean(r) (luminance), so that dim sides do not dominate.
struct Spread {
  double median, p95;
};
Spread spread(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& r) {
  auto lum = [](const glm::vec3& c) { return 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b; };
  double mean = 0.0;
  for (const glm::vec3& c : r) mean += lum(c) / double(r.size());
  std::vector<double> e;
  for (size_t i = 0; i < a.size(); ++i)
    if (lum(r[i]) >= 0.1 * mean) e.push_back(std::fabs(lum(a[i]) - lum(r[i])) / mean);
  std::sort(e.begin(), e.end());
  return {e[e.size() / 2], e[size_t(0.95 * double(e.size() - 1))]};
}

// The stored operator (defaults: in this small scene clusters of up to 4 vertex sides, cluster
// rows of 96 entries on average (each up to 255) and two gradient rows of 24, no rows of their
// own) against the uncompressed one, under a sun shining into the cavity at 30° off its axis: a
// sharp lit patch, the hard case. The stored one bounces the sun's SH through the bake's own
// transfer and only the rest through the operator (a control variate), as `prt relight` does.
// What it gives up is where within a cluster and within a merged node the light lands. Measured
// over the lit sides: median 2.5%, p95 27% of the mean bounce; the tail is the slab's underside,
// 0.1 above the floor in the shadow it casts, where the bounce changes across a few vertices.
// Without the control variate: median 4.5%, p95 38%. The bounds (4%, 33%) hold the measured
// accuracy and catch a lost control variate, a row that loses weight or lands it on the wrong
// node. With rows of their own asked for, some vertex sides (near the slab, where the walls meet
// it) keep one, and not many.
TEST(BounceOperator, CompressedStaysNearTheUncompressed) {
  Scene s = test::makeColouredRoom(24, 48);
  bakeScene(s, 256, 3, 7);
  const BounceOperator full = [&] {
    bake::OperatorSettings one;
    one.clusterSize = 1;
    return bake::buildBounceOperator(s, one, 3, 7, true);
  }();
  const BounceOperator op = bake::buildBounceOperator(s, bake::OperatorSettings{}, 3, 7);
  EXPECT_EQ(op.vertexRows.entries(), 0u);
  EXPECT_LE(op.clusters, op.vertexSides / 2);
  {
    bake::OperatorSettings withOwn;
    withOwn.rowLength = 16;
    const BounceOperator o = bake::buildBounceOperator(s, withOwn, 3, 7);
    size_t own = 0;
    for (size_t v = 0; v < o.vertexRows.rows(); ++v) own += o.vertexRows.start[v + 1] > o.vertexRows.start[v];
    std::printf("[ measured ] with rows of their own asked for: %zu of %u vertex sides keep one\n", own, o.vertexSides);
    EXPECT_GT(own, 0u);
    EXPECT_LT(own, size_t(o.vertexSides) / 4);
  }
  DirectLight sun;
  sun.direction = glm::normalize(glm::dvec3(0.5, 0.866, 0.0));
  sun.irradiance = glm::dvec3(3.0, 2.5, 2.0);
  const sh::ShRgb sunSh = sun.project(3);
  const bake::DirectIrradiance e0 = bake::shadowedDirectIrradiance(s, {sun});
  bake::OperatorLighting a(s, full, false), b(s, op, false);
  const bake::DirectIrradiance x = a.lightFrom(e0, nullptr, nullptr, sh::ShRgb(3));
  for (const sh::ShRgb* directSh : {&sunSh, static_cast<const sh::ShRgb*>(nullptr)}) {
    const bake::DirectIrradiance y = b.lightFrom(e0, directSh, nullptr, sh::ShRgb(3));
    const Spread d = spread(flat(y.front, y.back), flat(x.front, x.back));
    std::printf("[ measured ] compressed against uncompressed%s: median %.2f%%, p95 %.2f%% (%u clusters)\n",
                directSh ? ", SH through the transfer" : ", all through the operator", 100 * d.median, 100 * d.p95,
                op.clusters);
    if (directSh) {
      EXPECT_LT(d.median, 0.04);
      EXPECT_LT(d.p95, 0.33);
    }
  }
  // Without the gradient rows every member takes its cluster's mean (shaded by its transfer):
  // worse, as the cavity's walls see the lit patch from many distances.
  bake::OperatorSettings flatClusters;
  flatClusters.gradientRowLength = 0;
  const BounceOperator noGradients = bake::buildBounceOperator(s, flatClusters, 3, 7);
  EXPECT_EQ(noGradients.clusterGradients.entries(), 0u);
  bake::OperatorLighting c(s, noGradients, false);
  const bake::DirectIrradiance y = b.lightFrom(e0, &sunSh, nullptr, sh::ShRgb(3));
  const bake::DirectIrradiance z = c.lightFrom(e0, &sunSh, nullptr, sh::ShRgb(3));
  const Spread with = spread(flat(y.front, y.back), flat(x.front, x.back));
  const Spread without = spread(flat(z.front, z.back), flat(x.front, x.back));
  std::printf("[ measured ] without gradient rows: median %.2f%%, p95 %.2f%%\n", 100 * without.median,
              100 * without.p95);
  EXPECT_LT(with.median, without.median);
  EXPECT_LT(with.p95, without.p95);
}

// The cluster rows share one budget: `clusterRowLength` entries a row on average, each row up to
// 255 (rowCut: one error threshold for every row, found on a sample of the clusters, here all of
// them). A row cut shorter keeps its weight (each entry holds its node's whole share), so every
// cluster row of the stored operator gathers what the same cluster's row cut to 255 entries does (its weights' sum, to the
// codes' rounding: a row of a few coarse entries, each on the code just below or above it, may
// have no choice within a unit of its sum; measured 0.28% at worst, 0.003% in the mean); the rows
// whose cuts would merge the most light are longer than the average, and the others shorter.
TEST(BounceOperator, ClusterRowsShareOneBudget) {
  Scene s = test::makeColouredRoom(24, 48);
  bakeScene(s, 64, 2, 7);
  bake::OperatorSettings os;
  os.samples = 64;
  os.clusterRowLength = 24;
  const BounceOperator op = bake::buildBounceOperator(s, os, 2, 7);
  bake::OperatorSettings unbounded = os;  // every row as cut to 255 entries
  unbounded.clusterRowLength = BounceOperator::kMaxRowLength;
  const BounceOperator full = bake::buildBounceOperator(s, unbounded, 2, 7);
  ASSERT_EQ(op.clusters, full.clusters);
  const BounceOperator::Rows& r = op.clusterRows;
  size_t longest = 0, shorter = 0;
  double worst = 0.0, mean = 0.0;
  for (size_t c = 0; c < r.rows(); ++c) {
    const size_t n = r.start[c + 1] - r.start[c];
    longest = std::max(longest, n), shorter += n < 24;
    double a = 0.0, b = 0.0;
    for (uint32_t i = r.start[c]; i < r.start[c + 1]; ++i) a += r.weight[i];
    for (uint32_t i = full.clusterRows.start[c]; i < full.clusterRows.start[c + 1]; ++i)
      b += full.clusterRows.weight[i];
    worst = std::max(worst, std::fabs(a - b) / BounceOperator::kWeightOne);
    mean += std::fabs(a - b) / BounceOperator::kWeightOne / double(r.rows());
  }
  std::printf(
      "[ measured ] %zu cluster entries for %u clusters (budget 24 a row), the longest row %zu, %zu rows "
      "shorter than 24; row sums off by %.2g at worst, %.2g in the mean\n",
      r.entries(), op.clusters, longest, shorter, worst, mean);
  EXPECT_LE(r.entries(), size_t(24) * op.clusters);
  EXPECT_GT(r.entries(), size_t(20) * op.clusters);
  EXPECT_GT(longest, 36u);
  EXPECT_GT(shorter, 0u);
  EXPECT_LT(worst, 5e-3);
  EXPECT_LT(mean, 5e-4);
}

// `prt render`'s light change takes a cluster's direct light at its sample points, `prt relight`'s
// as its members' exact mean. The points are spread from the cluster's centre out, so the later
// ones stand at its rim; each counts for the share of the cluster nearest it, so that the points
// estimate the members' mean without leaning to the rim: under a sun that throws the slab's shadow
// into the cavity, the two agree in the mean over every vertex side.
TEST(BounceOperator, SamplePointsStandForTheirShareOfTheCluster) {
  Scene s = test::makeColouredRoom(24, 48);
  bakeScene(s, 256, 2, 7);
  const BounceOperator op = bake::buildBounceOperator(s, bake::OperatorSettings{}, 2, 7);
  DirectLight sun;
  sun.direction = glm::normalize(glm::dvec3(0.6, 0.8, 0.2));
  sun.irradiance = glm::dvec3(3.0);
  const bake::DirectIrradiance e0 = bake::shadowedDirectIrradiance(s, {sun});
  bake::OperatorLighting points(s, op, true), exact(s, op, false);
  const bake::DirectIrradiance a = points.light({sun}, nullptr, nullptr, sh::ShRgb(3));
  const bake::DirectIrradiance b = exact.lightFrom(e0, nullptr, nullptr, sh::ShRgb(3));
  const std::vector<glm::vec3> x = flat(a.front, a.back), y = flat(b.front, b.back);
  double sx = 0.0, sy = 0.0;
  for (size_t i = 0; i < x.size(); ++i) sx += luminance(x[i]), sy += luminance(y[i]);
  std::printf("[ measured ] bounce from sample points against the members' exact mean: %+.2f%%\n", 100 * (sx / sy - 1));
  EXPECT_NEAR(sx / sy, 1.0, 0.01);
}

// Inside a closed box every ray hits a wall: with E⁰ = 1 on every inner side, each bounce
// multiplies by ρ exactly, so E_b = Σ_{k=1..B} ρ^k at every inner side. Through the cluster rows
// that holds whatever the clusters and rows: weights sum to 1 per row (a bake keeps each row's
// sum as it puts the weights on the one-byte codes, to a unit of 1/65535 where the codes allow
// it); measured 2·10⁻⁵ of the sum. A gradient row's weights sum to 0, but its 24 entries merge
// far leaves into coarse nodes, and a node that holds one wall's inner side and the opposite
// wall's outer side (the same facing, here lit and dark) has their mean, so a side's gradient
// terms no longer cancel exactly: measured 0.34% of the sum. A lost factor (ρ, a bounce: ρ⁵ is
// 6% of the sum) is far outside either bound.
TEST(BounceOperator, ClosedBoxSumsTheBounceSeries) {
  const float rho = 0.6f;
  Scene s = test::makeScene({test::makeSlab({-1, -1, -1}, {1, 1, 1}, 0.25f)}, rho);
  s.materials[0].doubleSided = true;
  const int B = 4;
  bakeScene(s, 64, B, 3);
  double expect = 0.0;
  for (int k = 1; k <= B; ++k) expect += std::pow(rho, k);
  for (const int gradient : {0, bake::OperatorSettings{}.gradientRowLength}) {
    bake::OperatorSettings os;
    os.samples = 64;
    os.gradientRowLength = gradient;
    const BounceOperator op = bake::buildBounceOperator(s, os, B, 3);
    bake::DirectIrradiance e0;
    e0.front.resize(1);
    e0.back.assign(1, std::vector<glm::vec3>(s.meshes[0].vertexCount(), glm::vec3(1.0f)));
    e0.front[0].assign(s.meshes[0].vertexCount(), glm::vec3(0.0f));
    bake::OperatorLighting lighting(s, op, false);
    const bake::DirectIrradiance got = lighting.lightFrom(e0, nullptr, nullptr, sh::ShRgb(3));
    double worst = 0.0;
    for (const glm::vec3& v : got.back[0]) worst = std::max(worst, std::fabs(double(v.g) - expect));
    std::printf("[ measured ] closed box, gradient rows of %d: expected %.6f, worst deviation %.2g\n", gradient, expect,
                worst);
    EXPECT_LT(worst, (gradient == 0 ? 1e-3 : 5e-3) * expect);
    // The outer sides see only the sky: nothing bounces onto them.
    for (const glm::vec3& v : got.front[0]) EXPECT_EQ(v.g, 0.0f);
  }
}

// The open spherical cavity (unit sphere, opening of half-angle α) under a sun straight down
// its axis: the sun's light entering the opening, E_s π sin²α, lands on the wall; between two
// points of a sphere the form factor is dA / (4π R²), so its first bounce is the same
// everywhere on the wall, E1 = ρ E_s sin²α / 4, and each further bounce multiplies by ρ f,
// f = (1 + cos α) / 2 the wall's share of the sphere: E_b = E1 Σ_{k<B} (ρ f)^k at every wall
// point. Through the operator the direct light is taken at 4 shadow-ray points per cluster and
// each cluster gathers its members' 256 rays each, so single vertices scatter; their mean holds
// within 3%: the mesh (32 rings, an inscribed polyhedron whose lit area and rim differ from the
// sphere's) puts the exact gather 2.3% below the closed form (measured with clusters of one
// vertex and rows of 255 entries), Monte Carlo over 2k vertices × 256 rays adds ~0.5%, and any
// lost factor (π, ρ, a bounce) is far outside it.
TEST(BounceOperator, OpenCavityUnderASunMatchesItsClosedForm) {
  const double alpha = kPi / 4, rho = 0.5;
  Scene s = test::makeScene({test::makeCavity(alpha, 32, 64)}, float(rho));
  const int B = 3;
  bakeScene(s, 256, B, 5);
  const BounceOperator op = bake::buildBounceOperator(s, bake::OperatorSettings{}, B, 5);
  DirectLight sun;
  sun.direction = glm::dvec3(0, 1, 0);
  sun.irradiance = glm::dvec3(2.0);
  bake::OperatorLighting lighting(s, op, true);
  const double f = (1 + std::cos(alpha)) / 2;
  double expect = 0.0;
  for (int k = 0; k < B; ++k) expect += std::pow(rho * f, k);
  expect *= rho * 2.0 * std::sin(alpha) * std::sin(alpha) / 4;
  // Alone, and with the sun's SH bounced by the transfer and only the rest by the operator.
  const sh::ShRgb sunSh = sun.project(3);
  for (const sh::ShRgb* directSh : {static_cast<const sh::ShRgb*>(nullptr), &sunSh}) {
    const bake::DirectIrradiance got = lighting.light({sun}, directSh, nullptr, sh::ShRgb(3));
    double mean = 0.0;
    for (const glm::vec3& v : got.front[0]) mean += v.g / double(got.front[0].size());
    std::printf("[ measured ] open cavity under a sun%s: mean bounce %.5f, closed form %.5f\n",
                directSh ? " (SH part through the transfer)" : "", mean, expect);
    EXPECT_NEAR(mean / expect, 1.0, 0.03);
    EXPECT_GT(lighting.lastTimes().shadowRays, 0u);
  }
  // With the sun's light exact at every vertex (as `prt relight` has it) instead of one ray per
  // sample point: the same.
  const bake::DirectIrradiance e0 = bake::shadowedDirectIrradiance(s, {sun});
  const bake::DirectIrradiance got = lighting.lightFrom(e0, &sunSh, nullptr, sh::ShRgb(3));
  double mean = 0.0;
  for (const glm::vec3& v : got.front[0]) mean += v.g / double(got.front[0].size());
  std::printf("[ measured ] open cavity, the sun exact at every vertex: mean bounce %.5f\n", mean);
  EXPECT_NEAR(mean / expect, 1.0, 0.03);
}

// The same operator from one thread and from all: the same bytes.
TEST(BounceOperator, DeterministicForAnyThreadCount) {
  Scene s = test::makeColouredRoom();
  bakeScene(s, 64, 2, 9);
  bake::OperatorSettings os;
  os.samples = 64;
  os.threads = 1;
  const PackedOperator one = packOperator(bake::buildBounceOperator(s, os, 2, 9));
  os.threads = 0;
  const PackedOperator all = packOperator(bake::buildBounceOperator(s, os, 2, 9));
  EXPECT_EQ(one.header, all.header);
  EXPECT_TRUE(one.bytes == all.bytes);
}

// Built from the bake's own record of its first rays (SurfaceTransfer::gather), the operator
// traces none of them again and is the traced one to the bit (and a record moved is read as it
// is); so is it where the record lacks some sides (another rank's chunks, a resumed bake's),
// which are traced.
TEST(BounceOperator, KeptRaysGiveTheTracedOperator) {
  Scene s = test::makeColouredRoom();
  bake::BakeSettings bs;
  bs.samples = 128;
  bs.bounces = 2;
  bs.seed = 9;
  bs.keepGatherRays = 64;  // fewer than the samples: the records of the first 64 rays alone
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::GatherRecords kept = std::move(t.gather);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = 3;
  ASSERT_EQ(kept.rays, 64u);
  ASSERT_GT(kept.chunks.size(), 2u);
  size_t records = 0;
  for (const auto& c : kept.chunks) records += c.hits.size();
  EXPECT_GT(records, 0u);
  EXPECT_LT(records, t.stats.hitRecords);  // only the first 64 of 128 rays' records
  bake::OperatorSettings os;
  os.samples = 64;
  const PackedOperator traced = packOperator(bake::buildBounceOperator(s, os, 2, 9));
  EXPECT_TRUE(packOperator(bake::buildBounceOperator(s, os, 2, 9, false, nullptr, nullptr, &kept)).bytes ==
              traced.bytes);
  // The record is what is read: every kept hit moved to another barycentric point changes it.
  bake::GatherRecords moved = kept;
  for (auto& c : moved.chunks)
    for (bake::HitRecord& h : c.hits) h.b1 = uint16_t(h.b1 / 2), h.b2 = uint16_t(h.b2 / 2);
  EXPECT_FALSE(packOperator(bake::buildBounceOperator(s, os, 2, 9, false, nullptr, nullptr, &moved)).bytes ==
               traced.bytes);
  kept.chunks[1] = {};  // this chunk's sides are traced
  EXPECT_TRUE(packOperator(bake::buildBounceOperator(s, os, 2, 9, false, nullptr, nullptr, &kept)).bytes ==
              traced.bytes);
  os.samples = 32;  // a record of other rays than the operator's is not used
  EXPECT_TRUE(packOperator(bake::buildBounceOperator(s, os, 2, 9, false, nullptr, nullptr, &kept)).bytes ==
              packOperator(bake::buildBounceOperator(s, os, 2, 9)).bytes);
}

// The coloured room's operator from 64 rays a side, 2 bounces.
BounceOperator smallRoomOperator() {
  Scene s = test::makeColouredRoom();
  bakeScene(s, 64, 2, 9);
  bake::OperatorSettings os;
  os.samples = 64;
  return bake::buildBounceOperator(s, os, 2, 9);
}

// Packed and read back: the same operator; truncated, corrupt or of another version: refused,
// naming the part.
TEST(BounceOperator, PackedBytesAreCheckedWhenRead) {
  const BounceOperator op = smallRoomOperator();
  const PackedOperator p = packOperator(op);
  const BounceOperator back = unpackOperator(p.header, p.bytes.data(), p.bytes.size(), "f.glb");
  EXPECT_EQ(back.vertexRows.node, op.vertexRows.node);
  EXPECT_EQ(back.vertexRows.weight, op.vertexRows.weight);
  EXPECT_EQ(back.clusterRows.start, op.clusterRows.start);
  EXPECT_GT(op.clusterGradients.entries(), 0u);
  EXPECT_EQ(back.clusterGradients.start, op.clusterGradients.start);
  EXPECT_EQ(back.clusterGradients.node, op.clusterGradients.node);
  EXPECT_EQ(back.clusterGradients.weight, op.clusterGradients.weight);
  EXPECT_EQ(back.children, op.children);
  EXPECT_EQ(packOperator(back).bytes, p.bytes);
  auto refused = [&](const std::string& header, std::vector<uint8_t> bytes) -> std::string {
    try {
      unpackOperator(header, bytes.data(), bytes.size(), "f.glb");
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  std::vector<uint8_t> cut(p.bytes.begin(), p.bytes.end() - 8);
  EXPECT_NE(refused(p.header, cut).find("f.glb: bytes:"), std::string::npos) << refused(p.header, cut);
  std::vector<uint8_t> flipped = p.bytes;
  flipped[flipped.size() / 2] ^= 0x10;
  EXPECT_NE(refused(p.header, flipped).find("checksum"), std::string::npos);
  std::string v5 = p.header;
  v5.replace(v5.find("\"version\":4"), 11, "\"version\":5");
  EXPECT_NE(refused(v5, p.bytes).find("version 5"), std::string::npos) << refused(v5, p.bytes);
  EXPECT_NE(refused("{", p.bytes).find("not JSON"), std::string::npos);
}

// Version 4's one-byte weights: every code a different weight, each weight stored as the nearest
// code's (exact below 32, within 3% above, 1.9% from 256 up: the codes' values are rounded), and
// a row's sum kept when a bake puts its weights on the codes; the same for gradient weights.
TEST(BounceOperator, WeightCodesKeepEachRowsSum) {
  EXPECT_EQ(BounceOperator::weightOfCode(0), 0);
  EXPECT_EQ(BounceOperator::weightOfCode(255), BounceOperator::kWeightOne);
  for (int c = 0; c < 256; ++c) {
    EXPECT_EQ(BounceOperator::codeOfWeight(BounceOperator::weightOfCode(uint8_t(c))), c);
    if (c > 0) {
      EXPECT_GT(BounceOperator::weightOfCode(uint8_t(c)), BounceOperator::weightOfCode(uint8_t(c - 1)));
    }
  }
  double worst = 0.0, worstAbove = 0.0;  // over all weights, over those of 256 and more
  for (uint32_t q = 0; q <= BounceOperator::kWeightOne; ++q) {
    const int held = BounceOperator::weightOfCode(BounceOperator::codeOfWeight(uint16_t(q)));
    if (q < 32) {
      ASSERT_EQ(held, int(q));
    }
    const double e = q > 0 ? std::fabs(held - double(q)) / double(q) : 0.0;
    worst = std::max(worst, e);
    if (q >= 256) worstAbove = std::max(worstAbove, e);
  }
  std::printf("[ measured ] one-byte weights: largest relative error %.2f%%, %.2f%% from 256 up\n", 100 * worst,
              100 * worstAbove);
  EXPECT_LT(worst, 0.03);
  EXPECT_LT(worstAbove, 0.019);
  // A row of 96 weights spread over four decades: each held value is a code's, next to its
  // weight, and the sum moves by under one unit.
  std::vector<double> row;
  double sum = 0.0;
  for (int i = 0; i < 96; ++i) {
    row.push_back(BounceOperator::kWeightOne * 0.2 * std::pow(10.0, -4.0 * i / 95.0));
    sum += row.back();
  }
  const std::vector<uint16_t> held = BounceOperator::storedWeights(row);
  double heldSum = 0.0;
  for (size_t i = 0; i < row.size(); ++i) {
    EXPECT_EQ(BounceOperator::weightOfCode(BounceOperator::codeOfWeight(held[i])), held[i]);
    EXPECT_LT(std::fabs(held[i] - row[i]), 0.036 * row[i] + 1.0) << i;
    heldSum += held[i];
  }
  EXPECT_LT(std::fabs(heldSum - sum), 1.0) << heldSum << " " << sum;
  // Gradient weights: signed, magnitudes exact below 16, within 6% above, 3.7% from 256 up
  // (7.1% steps).
  for (int c = -127; c <= 127; ++c)
    EXPECT_EQ(BounceOperator::codeOfGradient(BounceOperator::gradientOfCode(int8_t(c))), c);
  double worstGradient = 0.0, worstGradientAbove = 0.0;
  for (int g = -32767; g <= 32767; ++g) {
    const int back = BounceOperator::gradientOfCode(BounceOperator::codeOfGradient(int16_t(g)));
    if (std::abs(g) < 16) {
      ASSERT_EQ(back, g);
    }
    const double e = g != 0 ? std::fabs(back - double(g)) / std::fabs(double(g)) : 0.0;
    worstGradient = std::max(worstGradient, e);
    if (std::abs(g) >= 256) worstGradientAbove = std::max(worstGradientAbove, e);
  }
  std::printf("[ measured ] one-byte gradient weights: largest relative error %.2f%%, %.2f%% from 256 up\n",
              100 * worstGradient, 100 * worstGradientAbove);
  EXPECT_LT(worstGradient, 0.06);
  EXPECT_LT(worstGradientAbove, 0.037);
  std::vector<double> signedRow;
  double signedSum = 0.0;
  for (int i = 0; i < 48; ++i) {
    signedRow.push_back((i % 3 == 0 ? -1.0 : 1.0) * 9000.0 * std::pow(10.0, -3.0 * i / 47.0));
    signedSum += signedRow.back();
  }
  const std::vector<int16_t> gheld = BounceOperator::storedGradients(signedRow);
  double gheldSum = 0.0;
  for (size_t i = 0; i < signedRow.size(); ++i) {
    EXPECT_EQ(BounceOperator::gradientOfCode(BounceOperator::codeOfGradient(gheld[i])), gheld[i]);
    EXPECT_LT(std::fabs(gheld[i] - signedRow[i]), 0.072 * std::fabs(signedRow[i]) + 1.0) << i;
    gheldSum += gheld[i];
  }
  EXPECT_LT(std::fabs(gheldSum - signedSum), 1.0) << gheldSum << " " << signedSum;
}

// A file of version 3 (two-byte weights; tests/data/corner_operator_v3.glb, a floor and a wall
// baked with --operator --samples 64 --no-refine) still reads, and written again as version 4
// every weight moves by at most one code's step.
TEST(BounceOperator, AVersion3FileStillReads) {
  const Scene s = loadScene(test::sourcePath("tests/data/corner_operator_v3.glb"));
  ASSERT_NE(s.bounceOperator, nullptr);
  const BounceOperator& v3 = *s.bounceOperator;
  EXPECT_EQ(v3.version, 3);
  EXPECT_GT(v3.clusterRows.entries(), 0u);
  const PackedOperator p = packOperator(v3);
  EXPECT_NE(p.header.find("\"version\":4"), std::string::npos);
  const BounceOperator v4 = unpackOperator(p.header, p.bytes.data(), p.bytes.size(), "corner.glb");
  ASSERT_EQ(v4.clusterRows.node, v3.clusterRows.node);
  for (size_t e = 0; e < v3.clusterRows.entries(); ++e)
    EXPECT_LE(std::abs(int(v4.clusterRows.weight[e]) - int(v3.clusterRows.weight[e])),
              std::max(1, int(std::lround(0.018 * v3.clusterRows.weight[e]))))
        << e;
}

// Version 4 writes each row's nodes as the walk down the two trees that finds them (one bit to go
// down, else one for in the row or not): a row that is not a cut of the trees cannot be written,
// and a walk that finds another count of nodes than its row's length is refused, naming the part.
TEST(BounceOperator, RowsAreWrittenAsCutsOfTheTrees) {
  const BounceOperator op = smallRoomOperator();
  const PackedOperator p = packOperator(op);
  const nlohmann::json h = nlohmann::json::parse(p.header);
  const size_t cutBytes = h["row_node_bytes"]["cluster"].get<size_t>();
  std::printf("[ measured ] cluster row nodes: %.2f bits an entry\n",
              8.0 * double(cutBytes) / double(op.clusterRows.entries()));
  EXPECT_LT(8 * cutBytes, 6 * op.clusterRows.entries());
  // A row holding the surface root and a node below it.
  BounceOperator notACut = op;
  BounceOperator::Rows& rows = notACut.clusterRows;
  const uint32_t below = op.children[2 * (op.surfaceRoot - op.leaves())];
  const uint32_t n0 = rows.start[1] - rows.start[0];
  rows.node.erase(rows.node.begin(), rows.node.begin() + n0);
  rows.weight.erase(rows.weight.begin(), rows.weight.begin() + n0);
  rows.node.insert(rows.node.begin(), {std::min(below, op.surfaceRoot), std::max(below, op.surfaceRoot)});
  rows.weight.insert(rows.weight.begin(), {30000, 30000});
  for (size_t r = 1; r < rows.start.size(); ++r) rows.start[r] = rows.start[r] - n0 + 2;
  try {
    (void)packOperator(notACut);
    ADD_FAILURE() << "a row that is not a cut was written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not a cut"), std::string::npos) << e.what();
  }
  // The first bit of the cluster rows' walks flipped (the checksum made to match): the first
  // row's walk then finds another count of nodes.
  size_t at = 0;
  auto skip = [&](size_t bytes) { at = (at + 3) / 4 * 4 + bytes; };
  skip(4 * op.leaves());                              // leaf weights
  skip(4 * op.children.size());                       // children
  skip(12 * size_t(op.clusters));                     // albedo
  skip(4 * (size_t(op.clusters) + 1));                // member starts
  skip(4 * size_t(op.vertexSides));                   // members
  skip(4 * op.skyBins());                             // sky bins
  skip(op.vertexSides);                               // vertex row lengths
  skip(h["row_node_bytes"]["vertex"].get<size_t>());  // vertex row nodes
  skip(op.vertexRows.entries());                      // vertex row weights
  skip(op.clusters);                                  // cluster row lengths
  at = (at + 3) / 4 * 4;                              // the cluster rows' walks
  std::vector<uint8_t> bytes = p.bytes;
  bytes[at] ^= 1;
  nlohmann::json bad = h;
  std::ostringstream sum;
  sum << std::hex << std::setw(16) << std::setfill('0') << fnv1a64(bytes.data(), bytes.size());
  bad["checksum"] = sum.str();
  try {
    (void)unpackOperator(bad.dump(), bytes.data(), bytes.size(), "f.glb");
    ADD_FAILURE() << "a flipped walk was read";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("f.glb: cluster row nodes: ", 0), 0u) << e.what();
  }
}

}  // namespace
}  // namespace prt
