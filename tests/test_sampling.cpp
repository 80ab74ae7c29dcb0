// Sampling triplets of prt/bake/sampling.h against their own pdfs, in the manner of Mitsuba 3's
// and Nori's ChiSquareTest: a histogram of samples is compared with the pdf integrated over the
// same cells, the pdf must integrate to one, and invert undoes sample over a grid of u.
// (test_bake.cpp keeps the older moment and round-trip checks of the same suite.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <numeric>
#include <random>
#include <vector>

#include "prt/bake/sampling.h"
#include "prt/math.h"

namespace prt {
namespace {

constexpr double kPiD = prt::kPi;

// ---- Statistics: the χ² tail probability.

/// Upper regularized incomplete gamma Q(a, x) = Γ(a, x) / Γ(a): the series for P = 1 - Q below
/// x = a + 1, Lentz's continued fraction for Q above (Numerical Recipes 6.2), both converged to
/// double precision. The χ² p-value with k degrees of freedom is Q(k/2, x/2).
double gammaQ(double a, double x) {
  if (x <= 0.0) return 1.0;
  double logPrefactor = -x + a * std::log(x) - std::lgamma(a);
  if (x < a + 1.0) {
    double term = 1.0 / a, sum = term;
    for (int n = 1; n < 100000 && std::fabs(term) > std::fabs(sum) * 1e-16; ++n) {
      term *= x / (a + n);
      sum += term;
    }
    return 1.0 - sum * std::exp(logPrefactor);
  }
  constexpr double kTiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / kTiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 100000; ++i) {
    double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::fabs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::fabs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    double delta = d * c;
    h *= delta;
    if (std::fabs(delta - 1.0) < 1e-16) break;
  }
  return std::exp(logPrefactor) * h;
}

double chiSquarePValue(double statistic, int dof) { return gammaQ(0.5 * dof, 0.5 * statistic); }

/// Composite adaptive Simpson on [a, b] to absolute tolerance `eps`, with Richardson's
/// correction. `depth` bounds the work where the integrand has a kink or step inside the
/// interval; a smooth pdf on a cell reaches 1e-13 within 4 or 5 levels.
double adaptiveSimpson(const std::function<double(double)>& f, double a, double b, double eps, int depth = 12) {
  struct Rec {
    const std::function<double(double)>& f;
    double step(double a, double fa, double m, double fm, double b, double fb, double whole, double eps, int depth) {
      double lm = 0.5 * (a + m), rm = 0.5 * (m + b), flm = f(lm), frm = f(rm);
      double left = (m - a) / 6.0 * (fa + 4.0 * flm + fm), right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
      double diff = left + right - whole;
      if (depth <= 0 || std::fabs(diff) <= 15.0 * eps) return left + right + diff / 15.0;
      return step(a, fa, lm, flm, m, fm, left, 0.5 * eps, depth - 1) +
             step(m, fm, rm, frm, b, fb, right, 0.5 * eps, depth - 1);
    }
  } rec{f};
  double m = 0.5 * (a + b), fa = f(a), fm = f(m), fb = f(b);
  return rec.step(a, fa, m, fm, b, fb, (b - a) / 6.0 * (fa + 4.0 * fm + fb), eps, depth);
}

// ---- Domains: charts in which equal cells in (x, φ) have equal measure.

/// The sphere in (cos θ, φ), where dω = d(cos θ) dφ, or the unit disk in (r², φ), where
/// dA = ½ d(r²) dφ. A point is a glm::vec3 (the disk's in z = 0); φ ∈ [-π, π] is atan2(y, x).
struct Chart {
  double xMin, xMax;
  double jacobian;  // measure per unit dx dφ
  glm::dvec3 (*point)(double x, double phi);
  double (*coordinate)(const glm::vec3& p);
  bool (*contains)(const glm::vec3& p);
};

const Chart kSphere{-1.0, 1.0, 1.0,
                    [](double z, double phi) {
                      double r = std::sqrt(std::max(0.0, 1.0 - z * z));
                      return glm::dvec3(r * std::cos(phi), r * std::sin(phi), z);
                    },
                    [](const glm::vec3& w) { return double(w.z); },
                    // sample* return unit vectors to float precision (a few ulp of 1)
                    [](const glm::vec3& w) { return std::fabs(glm::length(w) - 1.0f) < 1e-5f; }};

const Chart kDisk{
    0.0,
    1.0,
    0.5,
    [](double r2, double phi) {
      double r = std::sqrt(r2);
      return glm::dvec3(r * std::cos(phi), r * std::sin(phi), 0.0);
    },
    [](const glm::vec3& p) { return double(p.x) * p.x + double(p.y) * p.y; },
    [](const glm::vec3& p) { return p.z == 0.0f && double(p.x) * p.x + double(p.y) * p.y <= 1.0 + 1e-6; }};

// ---- The χ² goodness-of-fit test.

/// Cells: 32 in x by 64 in φ (Mitsuba's 1:2 aspect). On the sphere a cell is 1/16 in cos θ by
/// π/32 in φ, about 0.06 × 0.1 rad at the equator; the cosine pdf's kink at the horizon
/// (cos θ = 0) falls on a cell boundary.
constexpr int kCellsX = 32, kCellsPhi = 64;

/// N = 10⁶ samples. Power: a pdf off by a relative δ (RMS over the domain) adds a
/// noncentrality λ ≈ N·δ² to a χ² with about 2000 (sphere, disk) or 1000 (hemisphere) degrees of
/// freedom, whose rejection threshold lies about 2.8σ = 2.8·√(2·dof) ≈ 125 to 180 above its
/// mean at the α below: δ ≈ 1.5 to 2% is rejected (a cosine pdf of exponent 1.05 instead of 1
/// is δ ≈ 2.5%: ChiSquareRejectsAWrongExponent). Validity: the smallest expected count of any
/// triplet is ≈ 120 (the cosine pdf's horizon row), far above the 5 the χ² approximation needs,
/// so no cell of theirs is pooled. Cost: about 0.1 s each.
constexpr int kSamples = 1000000;

/// Family-wise significance 1% over the χ² tests expected to pass (disk, cosine hemisphere,
/// uniform sphere, and the harness's own control ChiSquareAcceptsAPeakedPdf), Šidák-corrected:
/// each is held to α = 1 - 0.99^(1/4) ≈ 0.0025. The seeds are fixed, so a run is deterministic;
/// α is the chance that a correct sampler fails for a seed chosen at random, that is the chance
/// that changing a seed (or an RNG) turns a correct sampler red. 1%, as in Mitsuba 3's tests.
constexpr int kPassingTests = 4;
const double kAlpha = 1.0 - std::pow(1.0 - 0.01, 1.0 / kPassingTests);

/// Cochran's rule: the χ² approximation needs an expected count of about 5 per cell. Smaller
/// cells are pooled, smallest first, into one (Mitsuba 3's ChiSquareTest does the same).
constexpr double kMinExpected = 5.0;

struct ChiSquareResult {
  double statistic = 0.0, pValue = 0.0, pdfIntegral = 0.0;
  int dof = 0, pooledCells = 0;
  int64_t outside = 0;    // samples off the domain (not unit length, outside the disk)
  int64_t inZeroPdf = 0;  // samples in cells where the pdf integrates to zero
};

/// u in [0, 1)² on the 2^-24 grid the bake's Sobol points use, from a 64-bit Mersenne twister
/// (whose output, unlike std::uniform_real_distribution's, is the same in every standard
/// library). Pseudo-random, not Sobol: χ² assumes independent samples, and a low-discrepancy
/// sequence would fit far better than chance and make the p-value meaningless.
glm::vec2 uniform2(std::mt19937_64& rng) {
  float a = float(rng() >> 40) * 0x1p-24f;
  float b = float(rng() >> 40) * 0x1p-24f;
  return {a, b};
}

ChiSquareResult chiSquareTest(const Chart& chart, const std::function<glm::vec3(glm::vec2)>& sample,
                              const std::function<double(const glm::vec3&)>& pdf, uint64_t seed) {
  const int cells = kCellsX * kCellsPhi;
  const double dx = (chart.xMax - chart.xMin) / kCellsX, dphi = 2.0 * kPiD / kCellsPhi;
  auto cellOf = [&](double x, double phi) {
    int i = std::clamp(int(std::floor((x - chart.xMin) / dx)), 0, kCellsX - 1);
    int j = std::clamp(int(std::floor((phi + kPiD) / dphi)), 0, kCellsPhi - 1);
    return i * kCellsPhi + j;
  };

  ChiSquareResult res;
  std::vector<double> observed(cells, 0.0), expected(cells, 0.0);
  std::mt19937_64 rng(seed);
  for (int s = 0; s < kSamples; ++s) {
    glm::vec3 p = sample(uniform2(rng));
    if (!chart.contains(p)) {
      ++res.outside;
      continue;
    }
    observed[cellOf(chart.coordinate(p), std::atan2(double(p.y), double(p.x)))] += 1.0;
  }

  // Each cell's probability by nested adaptive Simpson in double; 1e-12 per cell keeps the
  // quadrature error of the sum, and so of the pdf's integral, under 1e-8.
  for (int i = 0; i < kCellsX; ++i) {
    for (int j = 0; j < kCellsPhi; ++j) {
      double x0 = chart.xMin + i * dx, phi0 = -kPiD + j * dphi;
      double mass = adaptiveSimpson(
          [&](double x) {
            return adaptiveSimpson([&](double phi) { return pdf(glm::vec3(chart.point(x, phi))); }, phi0, phi0 + dphi,
                                   1e-13);
          },
          x0, x0 + dx, 1e-12);
      mass *= chart.jacobian;
      res.pdfIntegral += mass;
      expected[i * kCellsPhi + j] = mass * kSamples;
    }
  }

  std::vector<int> order(cells);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return expected[a] < expected[b]; });
  double pooledObserved = 0.0, pooledExpected = 0.0;
  int terms = 0;
  for (int c : order) {
    if (expected[c] == 0.0) {
      res.inZeroPdf += int64_t(observed[c]);
    } else if (expected[c] < kMinExpected || (pooledExpected > 0.0 && pooledExpected < kMinExpected)) {
      // a pool still under 5 takes the next (smallest) regular cell too
      pooledObserved += observed[c];
      pooledExpected += expected[c];
      ++res.pooledCells;
    } else {
      res.statistic += (observed[c] - expected[c]) * (observed[c] - expected[c]) / expected[c];
      ++terms;
    }
  }
  if (pooledExpected > 0.0) {
    res.statistic += (pooledObserved - pooledExpected) * (pooledObserved - pooledExpected) / pooledExpected;
    ++terms;
  }
  res.dof = terms - 1;  // the counts sum to N
  res.pValue = chiSquarePValue(res.statistic, res.dof);
  return res;
}

/// Into the XML report (--gtest_output=xml), to read how far a result is from its bound.
void record(const char* key, double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", value);
  ::testing::Test::RecordProperty(key, text);
}
void record(const ChiSquareResult& r) {
  record("chi_square", r.statistic);
  record("dof", r.dof);
  record("p_value", r.pValue);
  record("pdf_integral_minus_1", r.pdfIntegral - 1.0);
}

void expectFits(const ChiSquareResult& r) {
  record(r);
  EXPECT_EQ(r.outside, 0);
  EXPECT_EQ(r.inZeroPdf, 0);
  EXPECT_GT(r.pValue, kAlpha) << "χ² = " << r.statistic << " with " << r.dof << " degrees of freedom";
  // The pdf's integral over the domain: quadrature error < 1e-8 (above), float pdf values
  // rounded to ≈ 6e-8 relative. 1e-5 leaves a margin of 100 and still catches any wrong
  // constant (a 1/(2π) for 1/(4π) is off by 1).
  EXPECT_NEAR(r.pdfIntegral, 1.0, 1e-5);
}

// The disk has no pdf function of its own: the concentric map preserves area, so its density
// is the constant 1/π that sampleCosineHemisphere's cos θ / π rests on.
// The rim is let in with float rounding (r² ≤ 1 + 1e-6): the quadrature evaluates points on it,
// and a step there would send adaptive Simpson down to its depth limit.
double diskPdf(const glm::vec3& p) { return double(p.x) * p.x + double(p.y) * p.y <= 1.0 + 1e-6 ? 1.0 / kPiD : 0.0; }

// A cosine-power lobe about +Z, pdf (n+1)/(2π) cos^n θ, sampled by inverting its CDF
// cos θ = u^(1/(n+1)): the harness's own control, with a closed form independent of sampling.h.
glm::vec3 samplePowerCosine(glm::vec2 u, double n) {
  double z = std::pow(double(u.x), 1.0 / (n + 1.0)), r = std::sqrt(std::max(0.0, 1.0 - z * z));
  double phi = 2.0 * kPiD * u.y;
  return glm::vec3(glm::dvec3(r * std::cos(phi), r * std::sin(phi), z));
}
double powerCosinePdf(const glm::vec3& w, double n) {
  return w.z > 0.0f ? (n + 1.0) / (2.0 * kPiD) * std::pow(double(w.z), n) : 0.0;
}

// ---- The statistics themselves, against closed forms.

TEST(BakeSampling, ChiSquarePValueMatchesClosedForms) {
  for (double x : {0.1, 1.0, 3.841458820694124, 10.0, 40.0}) {
    // 1 dof: Q(1/2, x/2) = erfc(√(x/2)); 3.84 is the textbook 5% point.
    EXPECT_NEAR(chiSquarePValue(x, 1), std::erfc(std::sqrt(0.5 * x)), 1e-12 + 1e-10 * std::erfc(std::sqrt(0.5 * x)));
    // 2 dof: exp(-x/2).
    EXPECT_NEAR(chiSquarePValue(x, 2), std::exp(-0.5 * x), 1e-12 + 1e-10 * std::exp(-0.5 * x));
  }
  EXPECT_NEAR(chiSquarePValue(3.841458820694124, 1), 0.05, 1e-12);
  // Even dof 2k: Q(k, y) = e^-y Σ_{i<k} y^i / i! (a Poisson tail), at the sizes the tests use,
  // on both sides of the series / continued-fraction switch at y = k + 1.
  for (int k : {5, 500, 1000}) {
    for (double y : {0.8 * k, 1.0 * k, 1.05 * k, 1.2 * k}) {
      double sum = 0.0;
      for (int i = 0; i < k; ++i) sum += std::exp(-y + i * std::log(y) - std::lgamma(i + 1.0));
      EXPECT_NEAR(chiSquarePValue(2.0 * y, 2 * k), sum, 1e-9 + 1e-8 * sum) << "k " << k << ", y " << y;
    }
  }
}

// ---- The triplets.

TEST(BakeSampling, ConcentricDiskFitsItsPdf) {
  ChiSquareResult r = chiSquareTest(
      kDisk,
      [](glm::vec2 u) {
        glm::vec2 p = bake::sampleConcentricDisk(u);
        return glm::vec3(p, 0.0f);
      },
      diskPdf, 1);
  expectFits(r);
  EXPECT_EQ(r.pooledCells, 0);
}

TEST(BakeSampling, CosineHemisphereFitsItsPdf) {
  // Binned over the whole sphere: the lower half, where the pdf is zero, must get no sample.
  ChiSquareResult r = chiSquareTest(
      kSphere, bake::sampleCosineHemisphere, [](const glm::vec3& w) { return double(bake::cosineHemispherePdf(w.z)); },
      2);
  expectFits(r);
  EXPECT_EQ(r.pooledCells, 0);
}

TEST(BakeSampling, UniformSphereFitsItsPdf) {
  ChiSquareResult r = chiSquareTest(
      kSphere, bake::sampleUniformSphere, [](const glm::vec3&) { return double(bake::uniformSpherePdf()); }, 3);
  expectFits(r);
  EXPECT_EQ(r.pooledCells, 0);
}

// The probe bake's directions: sampleUniformSphere without libm, from the points' 24-bit digits.
glm::vec3 sphereFromBits(const glm::vec2& u) {
  return bake::uniformSphereFromBits(std::min(uint32_t(u.x * 0x1p24f), (1u << 24) - 1),
                                     std::min(uint32_t(u.y * 0x1p24f), (1u << 24) - 1));
}

TEST(BakeSampling, UniformSphereFromBitsFitsItsPdf) {
  ChiSquareResult r = chiSquareTest(
      kSphere, sphereFromBits, [](const glm::vec3&) { return double(bake::uniformSpherePdf()); }, 3);
  expectFits(r);
  EXPECT_EQ(r.pooledCells, 0);
}

TEST(BakeSampling, UniformSphereFromBitsIsTheSameMap) {
  // Every quarter turn's ends and middle, and a spread of other digits, against libm.
  std::vector<uint32_t> ys;
  for (uint32_t q = 0; q <= 4; ++q)
    for (int64_t o : {-2, -1, 0, 1, 2, (1 << 21) - 1, 1 << 21, (1 << 21) + 1})
      if (const int64_t v = int64_t(q) * (1 << 22) + o; v >= 0 && v < (1 << 24)) ys.push_back(uint32_t(v));
  for (uint32_t k = 0; k < 4096; ++k) ys.push_back(bake::sobol1Bits(k, 0x9e3779b9u));
  float worst = 0.0f;
  for (uint32_t by : ys)
    for (uint32_t bx : {0u, 1u, 1u << 23, (1u << 24) - 1, bake::sobol0Bits(by, 12345u)}) {
      const glm::vec3 d = bake::uniformSphereFromBits(bx, by);
      // The map in double (sampleUniformSphere's float φ = 2π·u alone is off by up to 4.8e-7).
      const double z = 1.0 - 2.0 * double(bx) * 0x1p-24, r = std::sqrt(std::max(0.0, 1.0 - z * z));
      const double phi = 2.0 * prt::kPi * double(by) * 0x1p-24;
      const glm::dvec3 e(r * std::cos(phi), r * std::sin(phi), z);
      worst = std::max(worst, float(glm::length(glm::dvec3(d) - e)));
    }
  EXPECT_LT(worst, 2.5e-7f);
}

// The surface bake's disk (sinCosQuarter instead of libm) against the map in double, over a
// grid that holds every wedge's edges (the diagonals, where the wedges meet, and the axes) and
// the centre.
TEST(BakeSampling, ConcentricDiskIsTheSameMap) {
  float worst = 0.0f;
  for (int i = 0; i <= 256; ++i)
    for (int j = 0; j <= 256; ++j) {
      const glm::vec2 u(float(i) / 256.0f, float(j) / 256.0f);
      const glm::vec2 p = bake::sampleConcentricDisk(u);
      const double ox = 2.0 * double(u.x) - 1.0, oy = 2.0 * double(u.y) - 1.0;
      glm::dvec2 e(0.0);
      if (ox != 0.0 || oy != 0.0) {
        const bool wide = std::fabs(ox) > std::fabs(oy);
        const double r = wide ? ox : oy, t = wide ? prt::kPi / 4 * (oy / ox) : prt::kPi / 2 - prt::kPi / 4 * (ox / oy);
        e = r * glm::dvec2(std::cos(t), std::sin(t));
      }
      worst = std::max(worst, float(glm::length(glm::dvec2(p) - e)));
    }
  EXPECT_LT(worst, 2.5e-7f);
}

// ---- The harness can tell: a peaked lobe passes with pooling, a slightly wrong pdf fails.

TEST(BakeSampling, ChiSquareAcceptsAPeakedPdf) {
  // cos^20: the horizon rows expect far fewer than 5 samples, so pooling is exercised.
  ChiSquareResult r = chiSquareTest(
      kSphere, [](glm::vec2 u) { return samplePowerCosine(u, 20.0); },
      [](const glm::vec3& w) { return powerCosinePdf(w, 20.0); }, 4);
  expectFits(r);
  EXPECT_GT(r.pooledCells, 0);
}

TEST(BakeSampling, ChiSquareRejectsAWrongExponent) {
  // The bake's cosine sampler against a cos^1.05 pdf, normalized, so only the shape is wrong:
  // by 0.05·(ln cos θ + 1/2) relative, 2.5% RMS, λ ≈ N·δ² ≈ 600. Measured p: 4e-36 here and
  // 6e-21 for the swapped pair below; 1e-10 is far below kAlpha and far above both.
  ChiSquareResult r = chiSquareTest(
      kSphere, bake::sampleCosineHemisphere, [](const glm::vec3& w) { return powerCosinePdf(w, 1.05); }, 5);
  record(r);
  EXPECT_NEAR(r.pdfIntegral, 1.0, 1e-5);
  EXPECT_LT(r.pValue, 1e-10) << "χ² = " << r.statistic << " with " << r.dof << " degrees of freedom";
  // And a sampler of the wrong exponent against the right pdf.
  r = chiSquareTest(
      kSphere, [](glm::vec2 u) { return samplePowerCosine(u, 1.05); },
      [](const glm::vec3& w) { return double(bake::cosineHemispherePdf(w.z)); }, 6);
  record("sampler_chi_square", r.statistic);
  record("sampler_p_value", r.pValue);
  EXPECT_LT(r.pValue, 1e-10) << "χ² = " << r.statistic << " with " << r.dof << " degrees of freedom";
}

// ---- invert undoes sample on a grid of u.

/// u at the centres of a 256 × 256 grid: the edges are left out because there the inverse is
/// not unique (u.x = 0 is the sphere's pole, where every u.y gives the same direction).
template <class Sample, class Invert>
void expectInverts(Sample sample, Invert invert, float tolerance) {
  constexpr int kGrid = 256;
  float worst = 0.0f;
  for (int i = 0; i < kGrid; ++i) {
    for (int j = 0; j < kGrid; ++j) {
      glm::vec2 u((i + 0.5f) / kGrid, (j + 0.5f) / kGrid);
      glm::vec2 back = invert(sample(u));
      float err = std::max(std::fabs(back.x - u.x), std::fabs(back.y - u.y));
      worst = std::max(worst, err);
      ASSERT_LE(err, tolerance) << "u = (" << u.x << ", " << u.y << ") -> (" << back.x << ", " << back.y << ")";
    }
  }
  record("worst_error", worst);
}

// Tolerances: each round trip is about ten float operations on values of order 1, trigonometry
// and atan2 included (each within an ulp or two of 6e-8), so errors of a few 1e-7 are rounding;
// 2e-6 is seven times the largest seen on this grid (3e-7). A wrong branch, wedge or period is off by
// 1e-2 or more.
TEST(BakeSampling, ConcentricDiskInvertsOnAGrid) {
  expectInverts(bake::sampleConcentricDisk, bake::invertConcentricDisk, 2e-6f);
}

TEST(BakeSampling, CosineHemisphereInvertsOnAGrid) {
  expectInverts(bake::sampleCosineHemisphere, bake::invertCosineHemisphere, 2e-6f);
}

TEST(BakeSampling, UniformSphereInvertsOnAGrid) {
  expectInverts(bake::sampleUniformSphere, bake::invertUniformSphere, 2e-6f);
}

}  // namespace
}  // namespace prt
