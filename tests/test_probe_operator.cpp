// The probes' rows of the bounce operator (BounceOperator::ProbeRows, prt/bake/bounce_operator.h):
// uncompressed, they are the probe bake's own bounced transfer; the open plane under a sun
// against its closed form; the stored rows against the uncompressed ones; determinism; and a
// grid they do not belong to, or corrupt bytes, refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "baked_scene.h"
#include "harness.h"
#include "prt/bake/bounce_operator.h"
#include "prt/bake/direct_light.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/surface_bake.h"
#include "prt/bake/surface_layout.h"
#include "prt/bounce_operator.h"
#include "prt/math.h"
#include "prt/probe_grid.h"
#include "prt/sh.h"
#include "test_scenes.h"

namespace prt {
namespace {

// A baked scene (test::bakeInPlace) and its lower-order transfer.
std::vector<std::vector<glm::vec3>> bakeScene(Scene& s, int samples, int bounces, uint64_t seed) {
  return test::bakeInPlace(s, samples, bounces, seed, /*lowerOrder=*/true);
}

ProbeGrid roomProbes(const Scene& s, const std::vector<std::vector<glm::vec3>>& lower, int samples, uint64_t seed) {
  bake::ProbeSettings ps;
  ps.dims = glm::ivec3(3, 3, 3);
  ps.boundsMin = glm::dvec3(-0.6);
  ps.boundsMax = glm::dvec3(0.6);
  ps.samples = samples;
  ps.bounces = 2;
  ps.seed = seed;
  ps.region = bake::ProbeSettings::Region::Everywhere;
  return bake::bakeProbes(s, lower, ps);
}

sh::ShRgb someLight() {
  sh::ShRgb l(3);
  for (int i = 0; i < 9; ++i) l.c[size_t(i)] = glm::vec3(1.0f + 0.1f * i, 0.5f - 0.05f * i, 0.3f + 0.02f * i);
  return l;
}

double largest(const std::vector<glm::vec3>& v) {
  double m = 0.0;
  for (const glm::vec3& c : v)
    m = std::max({m, double(std::fabs(c.r)), double(std::fabs(c.g)), double(std::fabs(c.b))});
  return m;
}

// With clusters of one vertex side and rows that keep every leaf, each cluster's value set to
// ρ · t_{K−1} · l (its side's lower-order transfer, what the probe bake's lit hits send), the
// probes' rows give the probe bake's own bounced part (M − M⁰) · l: the same rays (the probe's
// stream, its first samples), the same barycentrics, sides and albedo. What differs is rounding:
// the probe bake keeps the lit rows as halves (2⁻¹¹ relative, at random over ~100 hits), so 2e-3
// of the largest coefficient, while a wrong ray stream, side or factor of π is off by percents.
TEST(ProbeOperator, UncompressedRowsAreTheProbesBouncedTransfer) {
  Scene s = test::makeColouredRoom();
  const auto lower = bakeScene(s, 128, 2, 7);
  const ProbeGrid grid = roomProbes(s, lower, 256, 7);
  bake::OperatorSettings os;
  os.samples = 128;
  os.clusterSize = 1;
  os.probeSamples = 256;
  bake::ProbeShRows full;
  const BounceOperator op = bake::buildBounceOperator(s, os, 2, 7, /*uncompressed=*/true, &grid, &full);
  ASSERT_TRUE(op.probeRows.present());
  const bake::Layout lay = bake::makeLayout(s);
  const sh::ShRgb l = someLight();
  std::vector<glm::vec3> values(op.nodes(), glm::vec3(0.0f));
  for (uint32_t c = 0; c < op.clusters; ++c) {
    const uint32_t v = op.members[op.memberStart[c]];
    const size_t k = lay.meshOfVertex[v];
    const size_t row = lay.localVertex(v) + (lay.isBack(v) ? s.meshes[k].vertexCount() : 0);
    values[c] = op.albedo[c] * sh::dot(lower[k].data() + row * 9, l.c.data(), 9);
  }
  std::vector<glm::vec3> got(grid.probeCount() * 9, glm::vec3(0.0f));
  bake::addProbeBounce(full, grid, values, got);
  const std::vector<glm::vec3> expect = relightProbes(grid, sh::ShRgb(3), l);
  double worst = 0.0;
  for (size_t i = 0; i < got.size(); ++i)
    for (int c = 0; c < 3; ++c) worst = std::max(worst, double(std::fabs(got[i][c] - expect[i][c])));
  std::printf("[ measured ] uncompressed probe rows against the probes' bounced transfer: worst %.3g of %.3g\n", worst,
              largest(expect));
  EXPECT_GT(largest(expect), 0.05);
  EXPECT_LT(worst, 2e-3 * largest(expect));
}

// ∫ y_j(ω) L dω over a square of half-size a, at height h below a point over its centre, of
// uniform radiance L = 1: the midpoint rule over 1000 × 1000 cells (dω = h dA / r³; the integrand
// is smooth, the rule's error ~1e-6 of the value).
std::vector<double> squareSh(double a, double h) {
  constexpr int kCells = 1000;
  std::vector<double> c(9, 0.0);
  double y[9];
  const double d = 2.0 * a / kCells;
  for (int i = 0; i < kCells; ++i)
    for (int j = 0; j < kCells; ++j) {
      const glm::dvec3 v(-a + (i + 0.5) * d, -h, -a + (j + 0.5) * d);
      const double r = glm::length(v);
      sh::evaluate(3, v / r, y);
      for (int k = 0; k < 9; ++k) c[size_t(k)] += y[k] * h * d * d / (r * r * r);
    }
  return c;
}

// A probe at height 1 above a plane of albedo ρ (400 × 400, so that it fills the lower
// hemisphere but for 0.5% of its solid angle) lit by a sun of irradiance E at 30° from the
// vertical: the plane sends ρ E cosθ / π everywhere, whatever the bounce count (nothing comes
// back), and the probe's SH is that radiance over the square's solid angle (squareSh). The sun
// goes through the operator alone, or with its SH bounced by the probe's transfer and only the
// rest by the operator (the control variate prt probe uses), through the stored rows (96
// entries, each its rays' mean SH in 8 bits a coefficient). Tolerances: 4096 scrambled-Sobol
// directions estimate the square's share to ~0.3% (ProbeCavity measures it), and an entry's SH
// is off by at most half a step, 0.4% of its band's bound, at random over the entries: 1.5% of
// c₀ on every coefficient (measured: 0.7% at most), while a lost factor of π or the wrong
// hemisphere is off by the whole value.
TEST(ProbeOperator, OpenPlaneUnderASunMatchesItsClosedForm) {
  const double rho = 0.5, a = 200.0, h = 1.0;
  Scene s = test::makeScene({test::makePlane(glm::vec3(0.0f), float(2 * a), 40)}, float(rho));
  const auto lower = bakeScene(s, 64, 2, 3);
  bake::ProbeSettings ps;
  ps.dims = glm::ivec3(1);
  ps.boundsMin = glm::dvec3(-0.05, h - 0.05, -0.05);
  ps.boundsMax = glm::dvec3(0.05, h + 0.05, 0.05);
  ps.samples = 4096;
  ps.seed = 3;
  ps.region = bake::ProbeSettings::Region::Everywhere;
  const ProbeGrid grid = bake::bakeProbes(s, lower, ps);
  ASSERT_EQ(grid.probeCount(), 1u);
  bake::OperatorSettings os;
  os.samples = 64;
  os.probeSamples = 4096;
  const BounceOperator op = bake::buildBounceOperator(s, os, 2, 3, false, &grid);
  DirectLight sun;
  sun.direction = glm::normalize(glm::dvec3(0.5, std::sqrt(3.0) / 2, 0.0));
  sun.irradiance = glm::dvec3(2.0);
  const double L = rho * 2.0 * (std::sqrt(3.0) / 2) / kPi;
  const std::vector<double> expect = squareSh(a, h);
  bake::OperatorLighting lighting(s, op, true);
  const sh::ShRgb sunSh = sun.project(3);
  for (const sh::ShRgb* directSh : {static_cast<const sh::ShRgb*>(nullptr), &sunSh}) {
    lighting.light({sun}, directSh, nullptr, sh::ShRgb(3));
    std::vector<glm::vec3> c =
        directSh ? relightProbes(grid, sh::ShRgb(3), sunSh) : std::vector<glm::vec3>(9, glm::vec3(0.0f));
    bake::addProbeBounce(op, grid, lighting.nodeValues(), c);
    const double c0 = L * expect[0];
    for (int j = 0; j < 9; ++j) {
      std::printf("[ measured ] open plane%s: c%d %.5f, closed form %.5f\n", directSh ? " (control variate)" : "", j,
                  c[size_t(j)].g, L * expect[size_t(j)]);
      EXPECT_NEAR(c[size_t(j)].g, L * expect[size_t(j)], 0.015 * c0) << j;
    }
  }
}

// The probes' bounced light of a sun through the room's stored operator (defaults: clusters of up
// to 8 vertex sides, probe rows of 96 entries) against the same light through uncompressed probe
// rows (every leaf, SH in full) over the same clusters and node values: what cutting the rows to
// their length and storing each entry's SH in 8 bits give up. The sun shines into the cavity at
// 30° off its axis (a sharp lit patch, the hard case), all of it through the operator. Per probe
// the relative error |c − c_ref| / |c_ref| over its 27 values. Measured: median 2.0%, worst 5.2%
// over 27 probes (the cut alone: 1.9%, 5.2%; the 8-bit SH costs the rest); the bounds 3% and 8%
// leave room for other platforms' rounding, while rows of 32 entries are off by 23% and 33%
// and a wrong SH scale by the whole value.
TEST(ProbeOperator, StoredRowsStayNearTheUncompressed) {
  Scene s = test::makeColouredRoom();
  const auto lower = bakeScene(s, 128, 2, 11);
  const ProbeGrid grid = roomProbes(s, lower, 1024, 11);
  bake::OperatorSettings os;
  os.samples = 128;
  os.probeSamples = 1024;
  bake::ProbeShRows cut, all;
  const BounceOperator op = bake::buildBounceOperator(s, os, 2, 11, false, &grid, &cut);
  (void)bake::buildBounceOperator(s, os, 2, 11, true, &grid, &all);
  DirectLight sun;
  sun.direction = glm::normalize(glm::dvec3(0.5, std::sqrt(3.0) / 2, 0.0));
  sun.irradiance = glm::dvec3(2.0);
  bake::OperatorLighting lighting(s, op, true);
  lighting.light({sun}, nullptr, nullptr, sh::ShRgb(3));
  const size_t n = grid.probeCount() * 9;
  std::vector<glm::vec3> stored(n, glm::vec3(0.0f)), cutOnly(n, glm::vec3(0.0f)), ref(n, glm::vec3(0.0f));
  bake::addProbeBounce(op, grid, lighting.nodeValues(), stored);
  bake::addProbeBounce(cut, grid, lighting.nodeValues(), cutOnly);
  bake::addProbeBounce(all, grid, lighting.nodeValues(), ref);
  auto errors = [&](const std::vector<glm::vec3>& a) {
    std::vector<double> e;
    for (size_t p = 0; p < grid.probeCount(); ++p) {
      if (!(grid.validity[p] > 0.0f)) continue;
      double d = 0.0, r = 0.0;
      for (size_t j = 9 * p; j < 9 * p + 9; ++j) {
        const glm::vec3 x = a[j] - ref[j];
        d += double(glm::dot(x, x));
        r += double(glm::dot(ref[j], ref[j]));
      }
      e.push_back(std::sqrt(d / r));
    }
    std::sort(e.begin(), e.end());
    return std::pair<double, double>(e[e.size() / 2], e.back());
  };
  const auto [median, worst] = errors(stored);
  const auto [cutMedian, cutWorst] = errors(cutOnly);
  const uint64_t entries = op.probeRows.rows.entries();
  std::printf(
      "[ measured ] stored probe rows against uncompressed: median %.4f, worst %.4f (cut alone: %.4f, %.4f); "
      "%.1f entries a probe of %.1f\n",
      median, worst, cutMedian, cutWorst, double(entries) / double(grid.probeCount()),
      double(all.node.size()) / double(grid.probeCount()));
  EXPECT_LT(median, 0.03);
  EXPECT_LT(worst, 0.08);
}

// The same rows from one thread and from all: the same bytes.
TEST(ProbeOperator, DeterministicForAnyThreadCount) {
  Scene s = test::makeColouredRoom();
  const auto lower = bakeScene(s, 64, 2, 9);
  const ProbeGrid grid = roomProbes(s, lower, 256, 9);
  bake::OperatorSettings os;
  os.samples = 64;
  os.threads = 1;
  const PackedOperator one = packOperator(bake::buildBounceOperator(s, os, 2, 9, false, &grid));
  os.threads = 0;
  const PackedOperator every = packOperator(bake::buildBounceOperator(s, os, 2, 9, false, &grid));
  EXPECT_EQ(one.header, every.header);
  EXPECT_TRUE(one.bytes == every.bytes);
  EXPECT_NE(one.header.find("probe_rows"), std::string::npos);
}

// Packed and read back: the same rows. Rows of another grid (another lattice, seed or set of
// probes) refused by checkProbeRows, naming the file; corrupt or truncated bytes by the reader.
TEST(ProbeOperator, AMismatchedOrCorruptRowFileIsRefused) {
  Scene s = test::makeColouredRoom();
  const auto lower = bakeScene(s, 64, 2, 5);
  const ProbeGrid grid = roomProbes(s, lower, 256, 5);
  bake::OperatorSettings os;
  os.samples = 64;
  const BounceOperator op = bake::buildBounceOperator(s, os, 2, 5, false, &grid);
  const PackedOperator packed = packOperator(op);
  const BounceOperator back = unpackOperator(packed.header, packed.bytes.data(), packed.bytes.size(), "room.glb");
  EXPECT_EQ(back.probeRows.lattice, op.probeRows.lattice);
  EXPECT_EQ(back.probeRows.rows.node, op.probeRows.rows.node);
  EXPECT_EQ(back.probeRows.rows.weight, op.probeRows.rows.weight);
  EXPECT_EQ(back.probeRows.shape, op.probeRows.shape);
  EXPECT_NO_THROW(bake::checkProbeRows(back, grid, "room.glb"));
  auto refused = [&](const ProbeGrid& g, const char* what) {
    try {
      bake::checkProbeRows(back, g, "room.glb");
      ADD_FAILURE() << what << ": accepted";
    } catch (const Error& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.rfind("room.glb: probe rows: ", 0), 0u) << m;
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    }
  };
  ProbeGrid other = grid;
  other.dims.x += 1;
  refused(other, "another lattice");
  other = grid;
  other.info.seed += 1;
  refused(other, "another seed");
  other = grid;
  other.coord.pop_back();
  refused(other, "fewer probes");
  // A flipped byte among the probe rows (the last arrays): the checksum; a byte short: truncated.
  PackedOperator bad = packed;
  bad.bytes[bad.bytes.size() - 5] ^= 0x5a;
  EXPECT_THROW(unpackOperator(bad.header, bad.bytes.data(), bad.bytes.size(), "room.glb"), Error);
  EXPECT_THROW(unpackOperator(packed.header, packed.bytes.data(), packed.bytes.size() - 4, "room.glb"), Error);
  // A header whose probe rows name more entries than the bytes hold: refused, naming the part.
  std::string header = packed.header;
  const size_t at = header.find("\"entries\":");
  ASSERT_NE(at, std::string::npos);
  header.insert(at + 10, "1");
  try {
    (void)unpackOperator(header, packed.bytes.data(), packed.bytes.size(), "room.glb");
    ADD_FAILURE() << "a wrong entry count was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("room.glb"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace prt
