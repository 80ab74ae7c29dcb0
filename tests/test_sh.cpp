// Tests of the SH core (prt/sh.h): basis, clamped-cosine factors, projection, irradiance,
// rotation and windows. Analytic answers first; every tolerance says where it comes from.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "prt/error.h"
#include "prt/math.h"
#include "prt/sh.h"

namespace prt::sh {
namespace {

constexpr int kAll = kMaxBands;                   // 8 bands
constexpr int kAllCoeffs = numCoeffs(kMaxBands);  // 64

glm::dvec3 randomDir(std::mt19937& rng) {
  std::normal_distribution<double> g;
  glm::dvec3 d;
  do d = glm::dvec3(g(rng), g(rng), g(rng));
  while (glm::length(d) < 1e-6);
  return glm::normalize(d);
}

glm::dmat3 randomRotation(std::mt19937& rng) {
  std::uniform_real_distribution<double> angle(-180.0, 180.0);
  return rotationAxis(randomDir(rng), angle(rng));
}

ShRgb randomCoeffs(int bands, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  ShRgb c(bands);
  for (auto& v : c.c) v = glm::vec3(u(rng), u(rng), u(rng));
  return c;
}

// Σ c_i y_i(d) in double precision, so the functions handed to projectFunction carry no
// more rounding than their float return value.
glm::dvec3 reconstructD(const ShRgb& c, const glm::dvec3& d) {
  double y[kAllCoeffs];
  evaluate(c.bands, d, y);
  glm::dvec3 s(0.0);
  for (int i = 0; i < c.size(); ++i) s += glm::dvec3(c.c[i]) * y[i];
  return s;
}

// Legendre polynomial P_l(t) by Bonnet's recurrence.
double legendre(int l, double t) {
  double p0 = 1.0, p1 = t;
  if (l == 0) return p0;
  for (int k = 2; k <= l; ++k) {
    double p2 = ((2.0 * k - 1.0) * t * p1 - (k - 1.0) * p0) / k;
    p0 = p1;
    p1 = p2;
  }
  return p1;
}

// Orthonormal tangent frame (t1, t2, n) for a unit n.
void frame(const glm::dvec3& n, glm::dvec3& t1, glm::dvec3& t2) {
  glm::dvec3 a = std::abs(n.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  t1 = glm::normalize(glm::cross(a, n));
  t2 = glm::cross(n, t1);
}

// Fibonacci-sphere directions: near-uniform, deterministic; spacing ≈ √(4π/count) radians.
std::vector<glm::vec3> sphereDirs(int count) {
  std::vector<glm::vec3> out;
  const double golden = prt::kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    double z = 1.0 - (i + 0.5) * 2.0 / count;
    double r = std::sqrt(1.0 - z * z);
    out.emplace_back(glm::vec3(glm::dvec3(r * std::cos(golden * i), r * std::sin(golden * i), z)));
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Basis

TEST(ShBasis, IndexAndBand) {
  int i = 0;
  for (int l = 0; l < kAll; ++l)
    for (int m = -l; m <= l; ++m, ++i) {
      EXPECT_EQ(index(l, m), i);
      EXPECT_EQ(bandOf(i), l);
    }
  EXPECT_EQ(numCoeffs(kAll), 64);
}

// Projecting y_i must give the unit vector e_i. y_i·y_j has degree <= 14, and 64 Gauss-Legendre
// nodes × 128 φ samples integrate it exactly, so what is left is the float rounding of the
// result (ShRgb holds float, |c| <= 1: ~6e-8); 2e-6 leaves room for summing 8192 samples.
TEST(ShBasis, OrthonormalByProjection) {
  constexpr double kTol = 2e-6;
  for (int i = 0; i < kAllCoeffs; ++i) {
    ShRgb c = projectFunction(kAll, [i](const glm::dvec3& d) {
      double y[kAllCoeffs];
      evaluate(kAll, d, y);
      return glm::vec3(static_cast<float>(y[i]));
    });
    for (int j = 0; j < kAllCoeffs; ++j) EXPECT_NEAR(c.c[j].x, i == j ? 1.0 : 0.0, kTol) << "i=" << i << " j=" << j;
  }
}

// The same by an independent, naive rule: midpoints in z = cos θ (dω = dz dφ, so no Jacobian)
// and in φ. The uniform φ sum is exact for the frequencies |m ± m'| <= 14 < 32 that occur, so
// what is left is the z midpoint error (h²/24)(F'(1) - F'(-1)) of the φ-integrated product F,
// a polynomial of degree <= 14. For l = 7, m = 0: F'(±1) = ±15·P_7'(1) = ±420, so with
// h = 2/4000 the error is ~9e-6; 5e-5 allows the other (l, m).
TEST(ShBasis, OrthonormalByMidpointRule) {
  constexpr int kNz = 4000, kNphi = 32;
  constexpr double kTol = 5e-5;
  std::vector<double> gram(kAllCoeffs * kAllCoeffs, 0.0);
  const double h = 2.0 / kNz, dPhi = 2.0 * prt::kPi / kNphi;
  double y[kAllCoeffs];
  for (int a = 0; a < kNz; ++a) {
    const double z = -1.0 + (a + 0.5) * h;
    const double r = std::sqrt(1.0 - z * z);
    for (int b = 0; b < kNphi; ++b) {
      const double phi = (b + 0.5) * dPhi;
      evaluate(kAll, glm::dvec3(r * std::cos(phi), r * std::sin(phi), z), y);
      for (int i = 0; i < kAllCoeffs; ++i)
        for (int j = 0; j <= i; ++j) gram[i * kAllCoeffs + j] += y[i] * y[j];
    }
  }
  for (int i = 0; i < kAllCoeffs; ++i)
    for (int j = 0; j <= i; ++j)
      EXPECT_NEAR(gram[i * kAllCoeffs + j] * h * dPhi, i == j ? 1.0 : 0.0, kTol) << "i=" << i << " j=" << j;
}

// The Cartesian table of sh.h (Ramamoorthi & Hanrahan 2001; three.js SphericalHarmonics3).
// The constants are printed to 6 decimals (rounding <= 5e-7 each, times at most 3 for
// 3z² - 1), and evaluate() is float: 2e-6.
TEST(ShBasis, CartesianFormsBands0To2) {
  constexpr float kTol = 2e-6f;
  std::mt19937 rng(1);
  for (int k = 0; k < 100; ++k) {
    const glm::vec3 d(randomDir(rng));
    const float x = d.x, y = d.y, z = d.z;
    std::vector<float> v = evaluate(3, d);
    ASSERT_EQ(v.size(), 9u);
    EXPECT_NEAR(v[0], 0.282095f, kTol);
    EXPECT_NEAR(v[1], 0.488603f * y, kTol);
    EXPECT_NEAR(v[2], 0.488603f * z, kTol);
    EXPECT_NEAR(v[3], 0.488603f * x, kTol);
    EXPECT_NEAR(v[4], 1.092548f * x * y, kTol);
    EXPECT_NEAR(v[5], 1.092548f * y * z, kTol);
    EXPECT_NEAR(v[6], 0.315392f * (3.0f * z * z - 1.0f), kTol);
    EXPECT_NEAR(v[7], 1.092548f * x * z, kTol);
    EXPECT_NEAR(v[8], 0.546274f * (x * x - y * y), kTol);
  }
}

// Eight directions at once give each direction's bits, at every band count (the probe bake
// evaluates a packet of rays with evaluate8 where it evaluated them one by one). The 3-band AVX2
// kernel is the one written apart from evaluate(); the other counts check the lane layout.
TEST(ShBasis, EightLanesGiveEachDirectionsBits) {
  std::mt19937 rng(7);
  for (int bands = 1; bands <= kMaxBands; ++bands) {
    float x[8], y[8], z[8];
    for (int l = 0; l < 8; ++l) {
      const glm::vec3 d(randomDir(rng));
      x[l] = d.x, y[l] = d.y, z[l] = d.z;
    }
    // A pole, and axes with zeros of both signs (0 · y is −0 for y < 0: the products stay).
    x[4] = -0.0f, y[4] = -1.0f, z[4] = 0.0f;
    x[5] = 0.0f, y[5] = 0.0f, z[5] = -1.0f;
    x[6] = -1.0f, y[6] = -0.0f, z[6] = -0.0f;
    x[7] = -0.0f, y[7] = 1.0f, z[7] = -0.0f;
    std::vector<float> lanes(size_t(numCoeffs(bands)) * 8);
    evaluate8(bands, x, y, z, lanes.data());
    for (int l = 0; l < 8; ++l) {
      const std::vector<float> one = evaluate(bands, glm::vec3(x[l], y[l], z[l]));
      for (int i = 0; i < numCoeffs(bands); ++i) {
        float lane = lanes[size_t(8 * i + l)];
        EXPECT_EQ(0, std::memcmp(&lane, &one[size_t(i)], sizeof(float)))
            << "bands " << bands << " lane " << l << " coefficient " << i << ": " << lane << " vs " << one[size_t(i)];
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Clamped cosine

TEST(ShClampedCosine, KnownValues) {
  constexpr double kTol = 1e-12;  // closed forms in double
  EXPECT_NEAR(clampedCosineFactor(0), prt::kPi, kTol);
  EXPECT_NEAR(clampedCosineFactor(1), 2.0 * prt::kPi / 3.0, kTol);
  EXPECT_NEAR(clampedCosineFactor(2), prt::kPi / 4.0, kTol);
  EXPECT_NEAR(clampedCosineFactor(3), 0.0, kTol);
  EXPECT_NEAR(clampedCosineFactor(5), 0.0, kTol);
  EXPECT_NEAR(clampedCosineFactor(7), 0.0, kTol);
  EXPECT_NEAR(clampedCosineFactor(4), -prt::kPi / 24.0, kTol);
  EXPECT_NEAR(clampedCosineFactor(6), prt::kPi / 64.0, kTol);
}

// Â_l = 2π ∫₀¹ P_l(t) t dt by the midpoint rule: the integrand is a polynomial of degree
// <= 8 whose derivative is < 100 on [0, 1], so with h = 1/20000 the error
// (h²/24)|g'(1) - g'(0)| is < 1e-9 (times 2π); 1e-7 is a safe margin.
TEST(ShClampedCosine, MatchesNumericalIntegral) {
  constexpr int kN = 20000;
  constexpr double kTol = 1e-7;
  for (int l = 0; l < kAll; ++l) {
    double s = 0.0;
    for (int k = 0; k < kN; ++k) {
      double t = (k + 0.5) / kN;
      s += legendre(l, t) * t;
    }
    EXPECT_NEAR(clampedCosineFactor(l), 2.0 * prt::kPi * s / kN, kTol) << "l=" << l;
  }
}

// Projecting max(N·ω, 0) gives Â_l y_lm(N) (Funk-Hecke). The clamped cosine has a kink along
// the horizon, so the quadrature is no longer exact: for these normals the largest error is
// 7e-5 with 64 nodes and 9e-7 with 256 (measured). 2e-5 with 256 nodes leaves margin and is
// still far below the smallest factor that matters (Â_6 y ~ 1e-2).
TEST(ShClampedCosine, ProjectionOfLobe) {
  constexpr double kTol = 2e-5;
  std::mt19937 rng(2);
  for (int k = 0; k < 4; ++k) {
    const glm::dvec3 n = randomDir(rng);
    ShRgb c = projectFunction(
        kAll, [n](const glm::dvec3& d) { return glm::vec3(float(std::max(glm::dot(n, d), 0.0))); }, 256);
    double y[kAllCoeffs];
    evaluate(kAll, n, y);
    for (int i = 0; i < kAllCoeffs; ++i)
      EXPECT_NEAR(c.c[i].x, clampedCosineFactor(bandOf(i)) * y[i], kTol) << "i=" << i;
  }
}

// ---------------------------------------------------------------------------------------------
// Irradiance

// L = 1 everywhere: c_0 = 1 / y_0 = 2√π; E = ∫ max(N·ω, 0) dω = π for every N. Float: 1e-5.
TEST(ShIrradiance, UniformRadianceGivesPi) {
  std::mt19937 rng(3);
  for (int bands : {1, 3, kAll}) {
    ShRgb c(bands);
    c.c[0] = glm::vec3(float(2.0 * std::sqrt(prt::kPi)));
    for (int k = 0; k < 20; ++k) {
      const glm::vec3 n(randomDir(rng));
      EXPECT_NEAR(reconstruct(c, n).x, 1.0f, 1e-5f);
      const glm::vec3 e = irradiance(c, n);
      for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(e[ch], prt::kPi, 1e-5);
    }
  }
}

// E(N) = ∫_{N·ω>0} L(ω) (N·ω) dω, integrated directly in a frame about N: midpoints in
// t = N·ω ∈ [0, 1] and in the azimuth. L has bands <= 7, so the azimuthal sum (64 samples) is
// exact, and after it the integrand is a polynomial in t of degree <= 8 with derivative
// ~O(100): the midpoint error with h = 1/2000 is ~1e-6. irradiance() sums 64 float terms of
// size <= ~3: 1e-4 covers both.
TEST(ShIrradiance, MatchesDirectIntegration) {
  constexpr int kNt = 2000, kNphi = 64;
  constexpr double kTol = 1e-4;
  std::mt19937 rng(4);
  for (int bands : {3, kAll}) {
    for (int k = 0; k < 3; ++k) {
      const ShRgb c = randomCoeffs(bands, rng);
      const glm::dvec3 n = randomDir(rng);
      glm::dvec3 t1, t2;
      frame(n, t1, t2);
      glm::dvec3 e(0.0);
      for (int a = 0; a < kNt; ++a) {
        const double t = (a + 0.5) / kNt;
        const double r = std::sqrt(1.0 - t * t);
        for (int b = 0; b < kNphi; ++b) {
          const double phi = (b + 0.5) * 2.0 * prt::kPi / kNphi;
          const glm::dvec3 w = r * std::cos(phi) * t1 + r * std::sin(phi) * t2 + t * n;
          e += reconstructD(c, w) * t;
        }
      }
      e *= (1.0 / kNt) * (2.0 * prt::kPi / kNphi);
      const glm::vec3 got = irradiance(c, glm::vec3(n));
      for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(got[ch], e[ch], kTol) << "bands=" << bands << " channel " << ch;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Rotation. D is built in double from a recurrence over 7 bands; its elements are products of
// O(1) numbers, so orthogonality and composition hold to ~1e-13: 1e-10 is loose but would
// catch any wrong coefficient (errors are O(0.1) then).

constexpr double kRotTol = 1e-10;

TEST(ShRotation, IdentityGivesIdentity) {
  Rotation rot(kAll, glm::dmat3(1.0));
  for (int l = 0; l < kAll; ++l)
    for (int r = -l; r <= l; ++r)
      for (int c = -l; c <= l; ++c)
        EXPECT_NEAR(rot.element(l, r, c), r == c ? 1.0 : 0.0, kRotTol) << l << " " << r << " " << c;
}

TEST(ShRotation, BlocksAreOrthogonal) {
  std::mt19937 rng(5);
  for (int k = 0; k < 5; ++k) {
    Rotation rot(kAll, randomRotation(rng));
    for (int l = 0; l < kAll; ++l)
      for (int a = -l; a <= l; ++a)
        for (int b = -l; b <= l; ++b) {
          double s = 0.0;
          for (int c = -l; c <= l; ++c) s += rot.element(l, a, c) * rot.element(l, b, c);
          EXPECT_NEAR(s, a == b ? 1.0 : 0.0, kRotTol) << "l=" << l;
        }
  }
}

TEST(ShRotation, Composition) {
  std::mt19937 rng(6);
  for (int k = 0; k < 5; ++k) {
    const glm::dmat3 r1 = randomRotation(rng), r2 = randomRotation(rng);
    Rotation d1(kAll, r1), d2(kAll, r2), d12(kAll, r1 * r2);
    for (int l = 0; l < kAll; ++l)
      for (int a = -l; a <= l; ++a)
        for (int b = -l; b <= l; ++b) {
          double s = 0.0;
          for (int c = -l; c <= l; ++c) s += d1.element(l, a, c) * d2.element(l, c, b);
          EXPECT_NEAR(d12.element(l, a, b), s, kRotTol) << "l=" << l;
        }
  }
}

// The defining property: if g(ω) = f(R⁻¹ω) then coeffs(g) = D(R) coeffs(f). Projection with 16
// nodes is exact for these band-limited f (degree <= 14 < 32), so the difference is rounding of
// float values of size up to ~10 (64 terms): 2e-5.
TEST(ShRotation, RotateThenProjectEqualsProjectThenRotate) {
  constexpr double kTol = 2e-5;
  std::mt19937 rng(7);
  for (int bands = 1; bands <= kAll; ++bands) {
    for (int k = 0; k < 3; ++k) {
      const glm::dmat3 r = randomRotation(rng);
      const ShRgb c = randomCoeffs(bands, rng);
      const glm::dmat3 rInv = glm::transpose(r);
      ShRgb projected = projectFunction(
          bands, [&](const glm::dvec3& d) { return glm::vec3(reconstructD(c, rInv * d)); }, 16);
      ShRgb rotated = Rotation(bands, r).apply(c);
      ASSERT_EQ(rotated.bands, bands);
      for (int i = 0; i < c.size(); ++i)
        for (int ch = 0; ch < 3; ++ch)
          EXPECT_NEAR(rotated.c[i][ch], projected.c[i][ch], kTol)
              << "bands=" << bands << " i=" << i << " channel " << ch;
    }
  }
}

TEST(ShRotation, ApplyFloatMatchesElementsAndFewerBands) {
  std::mt19937 rng(8);
  const Rotation rot(kAll, randomRotation(rng));
  const ShRgb c = randomCoeffs(kAll, rng);
  std::vector<float> in(kAllCoeffs), out(kAllCoeffs);
  for (int i = 0; i < kAllCoeffs; ++i) in[i] = c.c[i].y;
  rot.apply(in.data(), out.data());
  for (int l = 0; l < kAll; ++l)
    for (int a = -l; a <= l; ++a) {
      double s = 0.0;
      for (int b = -l; b <= l; ++b) s += rot.element(l, a, b) * in[index(l, b)];
      EXPECT_NEAR(out[index(l, a)], s, 1e-5);  // float result of size ~3
    }
  // A rotation built for 8 bands rotates 3-band coefficients with its first blocks.
  const ShRgb small = rot.apply(resize(c, 3));
  const ShRgb full = rot.apply(c);
  ASSERT_EQ(small.bands, 3);
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(small.c[i].z, full.c[i].z, 1e-6);
}

TEST(ShRotation, RotationMatrices) {
  const glm::dmat3 ry = rotationY(90.0);
  const glm::dvec3 x = ry * glm::dvec3(1, 0, 0);
  EXPECT_NEAR(x.x, 0.0, 1e-12);
  EXPECT_NEAR(x.y, 0.0, 1e-12);
  EXPECT_NEAR(x.z, -1.0, 1e-12);
  const glm::dvec3 z = ry * glm::dvec3(0, 0, 1);  // right-handed about +Y: +Z -> +X
  EXPECT_NEAR(z.x, 1.0, 1e-12);
  // Right-handed about +Z: +X -> +Y.
  const glm::dvec3 xz = rotationAxis(glm::dvec3(0, 0, 2), 90.0) * glm::dvec3(1, 0, 0);
  EXPECT_NEAR(xz.y, 1.0, 1e-12);
  std::mt19937 rng(9);
  for (int k = 0; k < 5; ++k) {
    const glm::dvec3 axis = randomDir(rng);
    const glm::dmat3 r = rotationAxis(axis, 37.0 * (k + 1));
    const glm::dvec3 a = r * axis;  // the axis is fixed
    EXPECT_NEAR(glm::length(a - axis), 0.0, 1e-12);
    EXPECT_NEAR(glm::determinant(r), 1.0, 1e-12);
  }
}

// --env-rotate semantics: rotationY(90) turns lighting so that light from +X comes from -Z.
TEST(ShRotation, RotationYSendsLightFromXToMinusZ) {
  // Band 1 directly: the x coefficient (m = 1) moves into z (m = 0) with a minus sign.
  const Rotation rot(kAll, rotationY(90.0));
  EXPECT_NEAR(rot.element(1, 0, 1), -1.0, kRotTol);

  // A narrow band-limited lobe aimed at +X: the truncated delta c_i = y_i(+X).
  ShRgb lobe(kAll);
  std::vector<float> y = evaluate(kAll, glm::vec3(1, 0, 0));
  for (int i = 0; i < kAllCoeffs; ++i) lobe.c[i] = glm::vec3(y[i]);
  const float peak = reconstruct(lobe, glm::vec3(1, 0, 0)).x;  // Σ (2l+1)/4π = 64/4π
  EXPECT_NEAR(peak, 64.0 / (4.0 * prt::kPi), 1e-4);

  const ShRgb turned = rot.apply(lobe);
  EXPECT_NEAR(reconstruct(turned, glm::vec3(0, 0, -1)).x, peak, 1e-4);
  for (glm::vec3 d :
       {glm::vec3(1, 0, 0), glm::vec3(-1, 0, 0), glm::vec3(0, 1, 0), glm::vec3(0, -1, 0), glm::vec3(0, 0, 1)})
    EXPECT_LT(reconstruct(turned, d).x, 0.25f * peak);
  // The maximum over the sphere is at -Z: 20000 directions are ~1.4° apart.
  glm::vec3 best(0.0f);
  float bestValue = -1e30f;
  for (const glm::vec3& d : sphereDirs(20000)) {
    float v = reconstruct(turned, d).x;
    if (v > bestValue) {
      bestValue = v;
      best = d;
    }
  }
  EXPECT_GT(glm::dot(best, glm::vec3(0, 0, -1)), std::cos(2.0 * prt::kPi / 180.0));
}

// ---------------------------------------------------------------------------------------------
// Windows

TEST(ShWindow, Factors) {
  constexpr double kTol = 1e-12;
  for (int n = 1; n <= kAll; ++n)
    for (int l = 0; l < n; ++l) {
      EXPECT_EQ(windowFactor(Window::None, l, n), 1.0);
      const double h = windowFactor(Window::Hann, l, n);
      const double s = windowFactor(Window::Lanczos, l, n);
      EXPECT_LE(h, 1.0);
      EXPECT_GT(h, 0.0);
      EXPECT_LE(s, 1.0);
      EXPECT_GT(s, 0.0);
    }
  EXPECT_NEAR(windowFactor(Window::Hann, 0, 8), 1.0, kTol);
  EXPECT_NEAR(windowFactor(Window::Hann, 4, 8), 0.5, kTol);
  EXPECT_NEAR(windowFactor(Window::Hann, 2, 8), (1.0 + std::sqrt(0.5)) / 2.0, kTol);
  EXPECT_NEAR(windowFactor(Window::Lanczos, 0, 8), 1.0, kTol);
  EXPECT_NEAR(windowFactor(Window::Lanczos, 4, 8), 2.0 / prt::kPi, kTol);
  EXPECT_NEAR(windowFactor(Window::Lanczos, 2, 8), std::sqrt(0.5) / (prt::kPi / 4.0), kTol);
}

TEST(ShWindow, ParseAndName) {
  for (Window w : {Window::None, Window::Hann, Window::Lanczos}) EXPECT_EQ(parseWindow(windowName(w)), w);
  EXPECT_STREQ(windowName(Window::Hann), "hann");
  try {
    parseWindow("foo");
    FAIL() << "expected prt::Error";
  } catch (const prt::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("'foo'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("lanczos"), std::string::npos) << msg;
  }
}

TEST(ShWindow, ApplyWindowScalesEachBand) {
  std::mt19937 rng(10);
  const ShRgb c = randomCoeffs(5, rng);
  ShRgb w = c;
  applyWindow(w, Window::Hann);
  for (int i = 0; i < c.size(); ++i) EXPECT_NEAR(w.c[i].x, c.c[i].x * windowFactor(Window::Hann, bandOf(i), 5), 1e-7);
}

// A truncated delta rings: its reconstruction has negative lobes. Hann windowing must shrink
// them, both in absolute value and relative to the (lowered) peak.
TEST(ShWindow, HannReducesRinging) {
  ShRgb delta(kAll);
  std::vector<float> y = evaluate(kAll, glm::vec3(0, 0, 1));
  for (int i = 0; i < kAllCoeffs; ++i) delta.c[i] = glm::vec3(y[i]);
  ShRgb hann = delta;
  applyWindow(hann, Window::Hann);
  float minNone = 1e30f, minHann = 1e30f;
  for (const glm::vec3& d : sphereDirs(20000)) {
    minNone = std::min(minNone, reconstruct(delta, d).x);
    minHann = std::min(minHann, reconstruct(hann, d).x);
  }
  const float peakNone = reconstruct(delta, glm::vec3(0, 0, 1)).x;
  const float peakHann = reconstruct(hann, glm::vec3(0, 0, 1)).x;
  EXPECT_LT(minNone, 0.0f);
  EXPECT_GT(minHann, minNone);
  EXPECT_GT(minHann / peakHann, minNone / peakNone);
}

}  // namespace
}  // namespace prt::sh
