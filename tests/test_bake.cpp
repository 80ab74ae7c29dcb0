// Surface bake against closed forms: the unoccluded plane, the open spherical cavity (every
// bounce count, grey and coloured), determinism across thread counts, sampling triplets.
#include <gtest/gtest.h>
#include <bit>

#include <cmath>
#include <cstring>
#include <functional>
#include <random>

#include "prt/bake/ray_scene.h"
#include "prt/bake/sampling.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"
#include "prt/light.h"
#include "prt/math.h"
#include "prt/relight.h"
#include "prt/sh.h"
#include "test_scenes.h"

namespace prt {
namespace {

using bake::BakeSettings;

// ---- Sampling triplets: sample, pdf and invert agree with each other.

TEST(BakeSampling, CosineHemisphereInvertsAndHasItsPdf) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> uni(0.001f, 0.999f);
  double meanCos = 0.0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    glm::vec2 u(uni(rng), uni(rng));
    glm::vec3 w = bake::sampleCosineHemisphere(u);
    ASSERT_NEAR(glm::length(w), 1.0f, 1e-5f);
    ASSERT_GE(w.z, 0.0f);
    glm::vec2 back = bake::invertCosineHemisphere(w);
    ASSERT_NEAR(back.x, u.x, 2e-4f);
    ASSERT_NEAR(back.y, u.y, 2e-4f);
    meanCos += w.z;
  }
  // E[cos θ] under pdf cos θ/π is ∫cos² θ/π dω = 2/3. Standard error of 20000 samples of a
  // variable with deviation ≈ 0.24 is 0.0017: 0.01 is a 6-sigma bound.
  EXPECT_NEAR(meanCos / n, 2.0 / 3.0, 0.01);
  EXPECT_FLOAT_EQ(bake::cosineHemispherePdf(1.0f), 1.0f / prt::kPiF);
  EXPECT_EQ(bake::cosineHemispherePdf(-0.5f), 0.0f);
}

TEST(BakeSampling, UniformSphereInvertsAndHasItsPdf) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> uni(0.001f, 0.999f);
  for (int i = 0; i < 5000; ++i) {
    glm::vec2 u(uni(rng), uni(rng));
    glm::vec3 w = bake::sampleUniformSphere(u);
    ASSERT_NEAR(glm::length(w), 1.0f, 1e-5f);
    glm::vec2 back = bake::invertUniformSphere(w);
    ASSERT_NEAR(back.x, u.x, 1e-4f);
    ASSERT_NEAR(back.y, u.y, 1e-4f);
  }
  EXPECT_FLOAT_EQ(bake::uniformSpherePdf() * 4.0f * prt::kPiF, 1.0f);
}

TEST(BakeSampling, SobolPrefixesAreStratified) {
  // Every power-of-two prefix of the scrambled 2-D Sobol points is a (0, m, 2)-net: each of
  // the 16×16 elementary boxes of a 256-point prefix holds exactly one point.
  for (uint32_t scramble : {0u, 0x9e3779b9u, 0xdeadbeefu}) {
    std::vector<int> cells(256, 0);
    for (uint32_t i = 0; i < 256; ++i) {
      int x = int(bake::sobol0(i, scramble) * 16), y = int(bake::sobol1(i, scramble * 3u + 1u) * 16);
      ++cells[y * 16 + x];
    }
    for (int c : cells) EXPECT_EQ(c, 1);
  }
}

TEST(BakeSampling, Sobol1TableMatchesItsDefinition) {
  // sobol1 applies the generator matrix a byte at a time from a table; the definition XORs the
  // direction numbers v_0 = 2³¹, v_k = v_{k−1} ^ (v_{k−1} >> 1) of the index's set bits, one by
  // one. Every index below 2¹⁶ and spread indices up to 2³² − 1, with varied scrambles.
  auto definition = [](uint32_t i, uint32_t scramble) {
    uint32_t r = 0;
    for (uint32_t v = 1u << 31; i; i >>= 1, v ^= v >> 1)
      if (i & 1u) r ^= v;
    return float((r ^ scramble) >> 8) * 0x1p-24f;
  };
  for (uint32_t i = 0; i < (1u << 16); ++i)
    ASSERT_EQ(bake::sobol1(i, i * 2654435761u), definition(i, i * 2654435761u)) << i;
  for (uint64_t i = 0; i < (1ull << 32); i += 65521)
    ASSERT_EQ(bake::sobol1(uint32_t(i), 7u), definition(uint32_t(i), 7u)) << i;
  EXPECT_EQ(bake::sobol1(0xffffffffu, 0u), definition(0xffffffffu, 0u));
}

TEST(BakeSampling, FrameIsOrthonormal) {
  for (glm::vec3 n : {glm::vec3(0, 0, 1), glm::vec3(0, 0, -1), glm::normalize(glm::vec3(1, 2, -3))}) {
    bake::Frame f = bake::Frame::fromNormal(n);
    EXPECT_NEAR(glm::dot(f.t, f.b), 0.0f, 1e-6f);
    EXPECT_NEAR(glm::dot(f.t, f.n), 0.0f, 1e-6f);
    EXPECT_NEAR(glm::length(f.t), 1.0f, 1e-6f);
    EXPECT_NEAR(glm::length(f.b), 1.0f, 1e-6f);
    EXPECT_NEAR(glm::dot(glm::cross(f.t, f.b), f.n), 1.0f, 1e-5f);  // right-handed
  }
}

// ---- Ray casting: the geometric normal convention the bake relies on.

TEST(BakeRays, FrontFaceIsCounterClockwise) {
  Scene s = test::makeScene({test::makePlane({0, 0, 0}, 2.0f, 1)}, 1.0f);
  bake::RayScene rs(s);
  bake::Ray down, up;
  down.org = {0.1f, 1.0f, 0.1f};
  down.dir = {0, -1, 0};
  down.tfar = 10.0f;
  up = down;
  up.org.y = -1.0f;
  up.dir = {0, 1, 0};
  rs.intersect(&down, 1);
  rs.intersect(&up, 1);
  ASSERT_TRUE(down.hit());
  ASSERT_TRUE(up.hit());
  EXPECT_NEAR(down.tfar, 1.0f, 1e-5f);
  EXPECT_FALSE(down.backface());  // the plane faces +Y: seen from above, its front
  EXPECT_TRUE(up.backface());
  EXPECT_EQ(down.mesh, 0u);
}

// ---- The unoccluded plane: transfer is the closed form Â_l y_lm(N).

TEST(BakeSurface, UnoccludedPlaneMatchesClosedForm) {
  Scene s = test::makeScene({test::makePlane({0, 0, 0}, 2.0f, 4)}, 0.8f);
  BakeSettings set;
  set.bands = 4;
  set.samples = 1024;
  set.bounces = 2;
  bake::SurfaceTransfer t = bake::bakeSurface(s, set);
  float y[16];
  sh::evaluate(4, glm::vec3(0, 1, 0), y);
  for (size_t v = 0; v < s.meshes[0].vertexCount(); ++v) {
    for (int i = 0; i < 16; ++i) {
      float expected = float(sh::clampedCosineFactor(sh::bandOf(i))) * y[i];
      // All rays escape, so the estimate is (π/N)Σ y_i(ω_s) over a scrambled Sobol net of 1024
      // cosine-weighted points: quasi-Monte Carlo error well under 1e-2 for these smooth
      // integrands (measured ~1e-3); odd bands above 1 must vanish to the same accuracy.
      EXPECT_NEAR(t.perMesh[0][v * 16 + i].r, expected, 1e-2f) << "vertex " << v << " coeff " << i;
    }
  }
  // Units: a uniform sky of radiance 1 over an unoccluded upward surface of albedo ρ gives ρ.
  Scene baked = s;
  baked.transferBands = 4;
  baked.meshes[0].transfer = t.perMesh[0];
  auto lo = relightVertices(baked, projectUniform(4, glm::dvec3(1.0)));
  for (const glm::vec3& c : lo[0]) EXPECT_NEAR(c.g, 0.8f, 0.8f * 1e-3f);
}

TEST(BakeSurface, UnshadowedIsExactClosedForm) {
  Scene s = test::makeScene({test::makeCavity(prt::kPi / 3, 8, 16)}, 0.5f);
  BakeSettings set;
  set.shadowed = false;
  bake::SurfaceTransfer t = bake::bakeSurface(s, set);
  const MeshInstance& m = s.meshes[0];
  float y[9];
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    sh::evaluate(3, m.normals[v], y);
    for (int i = 0; i < 9; ++i)
      EXPECT_FLOAT_EQ(t.perMesh[0][v * 9 + i].b, float(sh::clampedCosineFactor(sh::bandOf(i))) * y[i]);
  }
  EXPECT_EQ(t.stats.rays, 0u);
}

// ---- The open spherical cavity.
//
// Every point inside a sphere sees any region of it with cosine-weighted fraction
// area / (4πR²) (the form factor from a point on a sphere to the sphere is constant), so each
// interior point sees the cap-shaped opening of half-angle α with f = (1 − cos α)/2, and the
// rest of the cavity with 1 − f. Under a uniform sky of radiance 1, after k bounces,
//   L_o = ρ f Σ_{j=0..k} (ρ(1−f))^j      (per colour channel).

struct CavityCase {
  glm::vec3 rho;
  int bounces;
};

double cavityExact(double rho, double f, int bounces) {
  double sum = 0.0, term = 1.0;
  for (int j = 0; j <= bounces; ++j, term *= rho * (1.0 - f)) sum += term;
  return rho * f * sum;
}

class BakeCavity : public ::testing::TestWithParam<CavityCase> {};

TEST_P(BakeCavity, MatchesGeometricSeries) {
  const CavityCase c = GetParam();
  const double alpha = prt::kPi / 3.0, f = (1.0 - std::cos(alpha)) / 2.0;
  Scene s = test::makeScene({test::makeCavity(alpha, 48, 96)}, 1.0f);
  s.materials[0].baseColorFactor = glm::vec4(c.rho, 1.0f);
  BakeSettings set;
  set.bands = 3;
  set.samples = 512;
  set.bounces = c.bounces;
  bake::SurfaceTransfer t = bake::bakeSurface(s, set);
  Scene baked = s;
  baked.transferBands = 3;
  baked.meshes[0].transfer = t.perMesh[0];
  auto lo = relightVertices(baked, projectUniform(3, glm::dvec3(1.0)));

  for (int ch = 0; ch < 3; ++ch) {
    const double exact = cavityExact(c.rho[ch], f, c.bounces);
    double sum = 0.0, worst = 0.0;
    for (const glm::vec3& v : lo[0]) {
      sum += v[ch];
      worst = std::max(worst, std::fabs(v[ch] - exact) / exact);
    }
    const double mean = sum / double(lo[0].size());
    // Mean over 4.6k vertices: the Monte Carlo noise averages out (< 0.1%); what remains is the
    // faceting of a 48×96 polyhedron (chords, flat triangles: ~0.1%) and linear interpolation
    // of the previous bounce across triangles (~0.2%). 1% bounds them with margin, and a
    // wrong factor (π, albedo applied twice, a lost bounce) moves the mean by 25% or more.
    EXPECT_NEAR(mean, exact, 0.01 * exact) << "channel " << ch;
    // Any single vertex: 512 cosine-weighted Sobol samples estimate f = 0.25 with a relative
    // error of a few percent at worst (scrambled nets: ~N^-0.75 convergence); 8% catches any
    // systematic error at the rim or the pole.
    EXPECT_LT(worst, 0.08) << "channel " << ch;
  }
}

INSTANTIATE_TEST_SUITE_P(Bounces, BakeCavity,
                         ::testing::Values(CavityCase{glm::vec3(0.5f), 0}, CavityCase{glm::vec3(0.5f), 1},
                                           CavityCase{glm::vec3(0.5f), 2}, CavityCase{glm::vec3(0.5f), 4},
                                           CavityCase{glm::vec3(0.9f, 0.5f, 0.1f), 3}));

// ---- Determinism: the same seed gives the same bits for any thread count.

TEST(BakeSurface, SameSeedSameResultAnyThreadCount) {
  Scene s = test::makeScene({test::makeCavity(prt::kPi / 3, 16, 32), test::makePlane({0, -1.5f, 0}, 3.0f, 8)}, 0.7f);
  BakeSettings set;
  set.samples = 128;
  set.bounces = 2;
  set.seed = 42;
  set.threads = 1;
  bake::SurfaceTransfer a = bake::bakeSurface(s, set);
  set.threads = 2;
  bake::SurfaceTransfer b = bake::bakeSurface(s, set);
  set.threads = 0;
  bake::SurfaceTransfer c = bake::bakeSurface(s, set);
  ASSERT_EQ(a.perMesh.size(), b.perMesh.size());
  for (size_t k = 0; k < a.perMesh.size(); ++k) {
    ASSERT_EQ(a.perMesh[k].size(), b.perMesh[k].size());
    EXPECT_EQ(0, std::memcmp(a.perMesh[k].data(), b.perMesh[k].data(), a.perMesh[k].size() * sizeof(glm::vec3)));
    EXPECT_EQ(0, std::memcmp(a.perMesh[k].data(), c.perMesh[k].data(), a.perMesh[k].size() * sizeof(glm::vec3)));
  }
  set.seed = 43;
  bake::SurfaceTransfer d = bake::bakeSurface(s, set);
  EXPECT_NE(0, std::memcmp(a.perMesh[0].data(), d.perMesh[0].data(), a.perMesh[0].size() * sizeof(glm::vec3)));
}

TEST(BakeSurface, ReceiversAreNotBakedAndCastNoShadow) {
  MeshInstance blocker = test::makePlane({0, 0.5f, 0}, 4.0f, 1);
  blocker.receiverOnly = true;
  Scene s = test::makeScene({test::makePlane({0, 0, 0}, 2.0f, 2), blocker}, 1.0f);
  s.meshes[1].receiverOnly = true;
  BakeSettings set;
  set.samples = 256;
  bake::SurfaceTransfer t = bake::bakeSurface(s, set);
  EXPECT_TRUE(t.perMesh[1].empty());
  // The receiver plane above does not shadow: t_0 = π y_0 exactly (every ray escapes).
  EXPECT_NEAR(t.perMesh[0][0].r, float(prt::kPi * 0.28209479), 1e-5f);
}

TEST(BakeSurface, RejectsBadSettings) {
  Scene s = test::makeScene({test::makePlane({0, 0, 0}, 1.0f, 1)}, 1.0f);
  for (auto change : std::vector<std::function<void(BakeSettings&)>>{
           [](BakeSettings& b) { b.bands = 0; }, [](BakeSettings& b) { b.bands = 9; },
           [](BakeSettings& b) { b.samples = 0; }, [](BakeSettings& b) { b.bounces = -1; },
           [](BakeSettings& b) { b.threads = -2; }}) {
    BakeSettings set;
    change(set);
    EXPECT_THROW(bake::bakeSurface(s, set), Error);
  }
}

}  // namespace
}  // namespace prt

// The bounces' halves (prt/bake/half.h) must round as F16C does, on every CPU: every half
// converts back exactly, and floats of every binade (normal, subnormal, overflow, ties) round
// to the same half as vcvtps2ph with round-to-nearest-even.
#include <cpuid.h>
#include <immintrin.h>

#include "prt/bake/half.h"

namespace {
// F16C: CPUID leaf 1, ECX bit 29 (clang 14, the sanitizer build, does not know
// __builtin_cpu_supports("f16c")).
bool cpuHasF16c() {
  unsigned a = 0, b = 0, c = 0, d = 0;
  return __get_cpuid(1, &a, &b, &c, &d) && (c & bit_F16C) != 0;
}
__attribute__((target("f16c"))) uint16_t f16cFromFloat(float f) {
  return uint16_t(_mm_extract_epi16(_mm_cvtps_ph(_mm_set1_ps(f), 0), 0));
}
__attribute__((target("f16c"))) float f16cToFloat(uint16_t h) {
  return _mm_cvtss_f32(_mm_cvtph_ps(_mm_set1_epi16(short(h))));
}
}  // namespace

TEST(BakeHalf, PortableConversionsMatchF16c) {
  if (!cpuHasF16c()) GTEST_SKIP() << "no F16C on this CPU";
  for (uint32_t h = 0; h < 0x10000u; ++h) {
    if ((h & 0x7c00u) == 0x7c00u && (h & 0x3ffu)) continue;  // NaNs: payloads may differ
    ASSERT_EQ(std::bit_cast<uint32_t>(prt::bake::floatFromHalf(uint16_t(h))),
              std::bit_cast<uint32_t>(f16cToFloat(uint16_t(h))))
        << h;
  }
  uint64_t s = 1;
  for (int i = 0; i < 2000000; ++i) {
    s = prt::bake::splitMix64(s);
    // Exponents around the half's range (2^-30 … 2^17), low mantissa bits random: ties included.
    const uint32_t x = uint32_t(s & 0x807fffffu) | ((97u + uint32_t(s >> 40) % 48u) << 23);
    const float f = std::bit_cast<float>(i % 4 == 0 ? (x & ~0x0fffu) | 0x1000u : x);
    ASSERT_EQ(prt::bake::halfFromFloat(f), f16cFromFloat(f)) << std::hexfloat << f;
  }
}
