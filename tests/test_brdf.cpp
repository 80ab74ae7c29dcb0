// The glTF metallic-roughness BRDF of prt/brdf.h against numerical integration: GGX's D
// normalised over projected area, the height-correlated visibility against Smith's Λ integrated
// by brute force, energy (directional albedo ≤ 1), GGX sampling against its pdf, and the
// split-sum DFG table against a Monte Carlo integration of the same lobe.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <vector>

#include "prt/brdf.h"
#include "prt/math.h"

namespace prt {
namespace {

constexpr double kPiD = prt::kPi;
const double kRoughness[] = {0.05, 0.1, 0.3, 0.5, 0.8, 1.0};

glm::dvec3 fromAngles(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

/// Composite Simpson's rule of f over [a, b] with n (even) intervals.
template <class F>
double simpson(F f, double a, double b, int n) {
  const double h = (b - a) / n;
  double sum = f(a) + f(b);
  for (int i = 1; i < n; ++i) sum += f(a + i * h) * (i % 2 ? 4.0 : 2.0);
  return sum * h / 3.0;
}

// ∫ D(h)(n·h) dω = 1: the microfacets' projected area is the macro surface's. Over θ (D does not
// depend on φ): 2π ∫ D(cos θ) cos θ sin θ dθ. 2·10⁵ Simpson intervals put ~300 points across
// the narrowest peak (α = 0.0025, width ~α rad), so the rule is exact to ~1e-9; 1e-6 catches
// any wrong constant (a missing π, α for α²).
TEST(BrdfGgx, DistributionIntegratesToOneOverProjectedArea) {
  for (double r : kRoughness) {
    const double alpha = r * r;
    const double integral =
        2.0 * kPiD *
        simpson([&](double t) { return brdf::ggxD(std::cos(t), alpha) * std::cos(t) * std::sin(t); }, 0.0, kPiD / 2,
                200000);
    EXPECT_NEAR(integral, 1.0, 1e-6) << "roughness " << r;
  }
}

/// Smith's Λ(ω) by brute force from its definition [Heitz 2014, eq. 17–18]: the projected area
/// of the microfacets facing ω is ∫ max(ω·m, 0) D(m) dm = cos θ (1 + Λ(ω)). Midpoint rule over
/// (θ_m, φ_m): 1600 × 1024 cells.
double lambdaByQuadrature(double cosTheta, double alpha) {
  const glm::dvec3 w(std::sqrt(1.0 - cosTheta * cosTheta), 0.0, cosTheta);
  const int nt = 1600, np = 1024;
  const double dt = kPiD / 2 / nt, dp = 2.0 * kPiD / np;
  double sum = 0.0;
  for (int i = 0; i < nt; ++i) {
    const double t = (i + 0.5) * dt, st = std::sin(t), ct = std::cos(t);
    const double d = brdf::ggxD(ct, alpha) * st * dt * dp;
    for (int j = 0; j < np; ++j) {
      const double p = (j + 0.5) * dp;
      sum += std::max(w.x * st * std::cos(p) + w.z * ct, 0.0) * d;
    }
  }
  return sum / cosTheta - 1.0;
}

// V = 1 / (4 (n·l)(n·v)(1 + Λ(l) + Λ(v))) with Λ integrated from D itself: this checks the
// closed form of Λ, the height-correlated combination and the 1/(4 n·l n·v) of the visibility.
// Tolerance 0.5% relative: the midpoint rule's error at the kink where ω·m = 0 and at D's peak
// (roughness ≥ 0.3, α ≥ 0.09, ≥ 50 cells across it) stays below 0.1% (the test passes at
// 0.2% too); the separable form G1(l)·G1(v) differs from the correlated one by Λ(l)Λ(v), over
// 1% at the grazing pairs tested.
TEST(BrdfSmith, VisibilityMatchesLambdaIntegratedFromTheDistribution) {
  const double cosines[] = {1.0, 0.8, 0.5, 0.2};
  for (double r : {0.3, 0.6, 1.0}) {
    const double alpha = r * r;
    std::vector<double> lambda;
    for (double c : cosines) {
      lambda.push_back(lambdaByQuadrature(c, alpha));
      EXPECT_NEAR(lambda.back(), brdf::smithLambda(c, alpha), 2e-3 * (1.0 + lambda.back()))
          << "roughness " << r << ", cos " << c;
    }
    for (size_t i = 0; i < 4; ++i)
      for (size_t j = 0; j < 4; ++j) {
        const double nl = cosines[i], nv = cosines[j];
        const double want = 1.0 / (4.0 * nl * nv * (1.0 + lambda[i] + lambda[j]));
        EXPECT_NEAR(brdf::smithVisibility(nl, nv, alpha), want, 5e-3 * want)
            << "roughness " << r << ", n·l " << nl << ", n·v " << nv;
      }
  }
}

/// ∫ f(l, v)(n·l) dl by importance sampling: GGX reflections for the specular lobe, cosine
/// directions for the diffuse one, n = +Z. 2¹⁶ stratified samples each.
brdf::Lobes directionalAlbedo(const brdf::MetallicRoughness& m, double nDotV) {
  const glm::dvec3 n(0, 0, 1), v(std::sqrt(1.0 - nDotV * nDotV), 0.0, nDotV);
  const double r = std::max(m.roughness, brdf::kMinRoughness), alpha = r * r;
  const int side = 256;
  brdf::Lobes sum;
  for (int i = 0; i < side; ++i)
    for (int j = 0; j < side; ++j) {
      const glm::dvec2 u((i + 0.5) / side, (j + 0.5) / side);
      const glm::dvec3 l = brdf::sampleGgxReflection(u, v, alpha);
      if (l.z > 0.0) sum.specular += brdf::evaluate(m, n, l, v).specular * l.z / brdf::pdfGgxReflection(l, v, alpha);
      // Cosine-weighted: pdf = (n·l)/π, so f (n·l)/pdf = π f.
      const double rr = std::sqrt(u.x), phi = 2.0 * kPiD * u.y;
      const glm::dvec3 c(rr * std::cos(phi), rr * std::sin(phi), std::sqrt(std::max(1.0 - u.x, 0.0)));
      if (c.z > 0.0) sum.diffuse += brdf::evaluate(m, n, c, v).diffuse * kPiD;
    }
  sum.diffuse /= double(side * side);
  sum.specular /= double(side * side);
  return sum;
}

// White furnace, lobe by lobe: a white metal (F = 1) reflects at most what it receives, the
// more the smoother (single scattering loses what bounces between microfacets); at α = 1 and a
// normal view D = 1/π and V = 1/(2(1 + n·l)), so E = ∫₀¹ μ/(1 + μ) dμ = 1 − ln 2 exactly. The
// diffuse lobe of a white dielectric without specular reflects exactly 1. The stratified
// estimate's error is below 0.3% (the DFG test below agrees with an independent estimator to
// that); tolerance 0.5%.
TEST(BrdfEnergy, NoLobeReflectsMoreThanItReceives) {
  for (double r : kRoughness)
    for (double nv : {1.0, 0.7, 0.4, 0.15, 0.05}) {
      brdf::MetallicRoughness metal;
      metal.metallic = 1.0, metal.roughness = r;
      const brdf::Lobes e = directionalAlbedo(metal, nv);
      EXPECT_LE(e.specular.x, 1.005) << "white metal, roughness " << r << ", n·v " << nv;
      EXPECT_GT(e.specular.x, 0.25) << "white metal, roughness " << r << ", n·v " << nv;
      EXPECT_EQ(e.diffuse.x, 0.0);
      brdf::MetallicRoughness matte;
      matte.metallic = 0.0, matte.roughness = r, matte.specular = 0.0;
      EXPECT_NEAR(directionalAlbedo(matte, nv).diffuse.x, 1.0, 1e-9);
    }
  brdf::MetallicRoughness rough;
  rough.metallic = 1.0;
  EXPECT_NEAR(directionalAlbedo(rough, 1.0).specular.x, 1.0 - std::log(2.0), 5e-3 * (1.0 - std::log(2.0)));
}

// The whole glTF dielectric (white base colour, ior 1.5). Appendix B weighs the diffuse lobe by
// 1 − F(v·h) for each light direction, and the specular lobe by F(v·h) at its own directions:
// at views towards the normal both see v·h near 1 and the sum stays ≤ 1 (+ the 0.5%
// tolerance) at every roughness; at grazing views the specular lobe takes F near 1 while the
// diffuse one keeps its (1 − F) of near-normal half vectors, and the sum exceeds 1: measured
// 1.060 at roughness 0.3 and n·v 0.4, 1.24 at n·v 0.15, 1.71 at roughness 0.05 and n·v 0.05
// (docs/bake.md, "Materials"). The test holds both sides: ≤ 1 at n·v ≥ 0.7, and the grazing
// excess within 25% at n·v 0.15, roughness ≥ 0.3 (without the diffuse weight 1 − F the
// sum is 1.30 at roughness 0.3).
TEST(BrdfEnergy, DielectricKeepsEnergyExceptAtGrazingViews) {
  for (double r : kRoughness)
    for (double nv : {1.0, 0.85, 0.7}) {
      brdf::MetallicRoughness m;
      m.metallic = 0.0, m.roughness = r;
      const brdf::Lobes e = directionalAlbedo(m, nv);
      EXPECT_LE(e.diffuse.x + e.specular.x, 1.005) << "roughness " << r << ", n·v " << nv;
      EXPECT_GT(e.diffuse.x, 0.95) << "roughness " << r << ", n·v " << nv;
    }
  for (double r : {0.3, 0.5, 0.8, 1.0}) {
    brdf::MetallicRoughness m;
    m.metallic = 0.0, m.roughness = r;
    const brdf::Lobes e = directionalAlbedo(m, 0.15);
    EXPECT_LE(e.diffuse.x + e.specular.x, 1.25) << "roughness " << r;
  }
  // The table docs/bake.md quotes: diffuse + specular = total per roughness and n·v.
  for (double r : kRoughness) {
    std::printf("white dielectric, roughness %.2f:", r);
    for (double nv : {1.0, 0.7, 0.4, 0.15, 0.05}) {
      brdf::MetallicRoughness m;
      m.metallic = 0.0, m.roughness = r;
      const brdf::Lobes e = directionalAlbedo(m, nv);
      std::printf("  n·v %.2f: %.3f + %.3f = %.3f", nv, e.diffuse.x, e.specular.x, e.diffuse.x + e.specular.x);
    }
    std::printf("\n");
  }
}

/// E[(1 − |v·h|)⁵] over l and v cosine-weighted, by the midpoint rule in (θ_v, θ_l, φ) with n
/// cells each (φ over [0, π] by symmetry).
double halfVectorFresnelMean(int n) {
  double sum = 0.0, weight = 0.0;
  const double h = kPiD / 2 / n;
  for (int a = 0; a < n; ++a) {
    const double tv = (a + 0.5) * h, wv = std::sin(2.0 * tv);
    for (int b = 0; b < n; ++b) {
      const double tl = (b + 0.5) * h, wl = std::sin(2.0 * tl);
      for (int c = 0; c < n; ++c) {
        const double lv = std::sin(tv) * std::sin(tl) * std::cos(kPiD * (c + 0.5) / n) + std::cos(tv) * std::cos(tl);
        const double m = 1.0 - std::sqrt((1.0 + lv) / 2.0);  // v·h = cos(half the angle between l and v)
        sum += wv * wl * m * m * m * m * m;
        weight += wv * wl;
      }
    }
  }
  return sum / weight;
}

// kHalfVectorFresnelMean by quadrature: 100³ cells give it within 1e-6 (the rule converges as
// h², measured: 50³ is 3.4e-6 off, 100³ 0.9e-6, 400³ 0.06e-6); tolerance 2e-6, against 1/21 =
// 0.048 for the same mean in n·l. Then dielectricDiffuseWeight against the definition: the mean
// of 1 − s·max(F(v·h)) over both directions.
TEST(BrdfEnergy, DielectricDiffuseWeightIsTheMeanOfOneMinusFresnel) {
  EXPECT_NEAR(brdf::kHalfVectorFresnelMean, halfVectorFresnelMean(100), 2e-6);
  EXPECT_NEAR(brdf::dielectricF0(1.5), 0.04, 1e-12);
  EXPECT_NEAR(brdf::dielectricDiffuseWeight(1.5, 1.0, glm::dvec3(1.0)), 0.956463, 1e-6);
  EXPECT_NEAR(brdf::schlickCosineAverage(0.04), 0.04 + 0.96 / 21.0, 1e-12);
  for (double ior : {1.0, 1.33, 1.5, 2.4})
    for (double s : {0.0, 0.5, 1.0})
      for (glm::dvec3 color : {glm::dvec3(1.0), glm::dvec3(2.0, 0.5, 1.0), glm::dvec3(40.0)}) {
        const double f0 = std::min(brdf::dielectricF0(ior) * std::max({color.x, color.y, color.z}), 1.0);
        const double want = 1.0 - s * (f0 + (1.0 - f0) * halfVectorFresnelMean(100));
        EXPECT_NEAR(brdf::dielectricDiffuseWeight(ior, s, color), want, 2e-6) << ior << " " << s;
      }
  // The diffuse lobe of evaluate() averaged over cosine-weighted views is the same number.
  brdf::MetallicRoughness m;
  m.metallic = 0.0;
  double sum = 0.0;
  for (int k = 0; k < 32; ++k) sum += directionalAlbedo(m, std::sqrt((k + 0.5) / 32)).diffuse.x;
  EXPECT_NEAR(sum / 32, brdf::dielectricDiffuseWeight(1.5, 1.0, glm::dvec3(1.0)), 1e-3);
}

// ---- Sampling: sample / pdf / invert against each other.

TEST(BrdfSampling, InvertUndoesSample) {
  for (double r : kRoughness)
    for (int i = 0; i < 32; ++i)
      for (int j = 0; j < 32; ++j) {
        const glm::dvec2 u((i + 0.5) / 32, (j + 0.5) / 32);
        const glm::dvec2 back = brdf::invertGgxHalfVector(brdf::sampleGgxHalfVector(u, r * r), r * r);
        EXPECT_NEAR(back.x, u.x, 1e-9);
        EXPECT_NEAR(back.y, u.y, 1e-9);
      }
}

// A histogram of 2·10⁵ sampled half vectors against the pdf integrated over the same cells
// (16 equal-probability θ rings × 8 φ sectors would make the test circular, so the rings are
// equal in θ): Pearson's χ² with 127 degrees of freedom must stay below 127 + 6·√254 (a
// 6-sigma bound in the normal approximation; p < 1e-7 for a correct sampler, and a pdf off by
// 5% in one ring fails it). Fixed seed.
TEST(BrdfSampling, HalfVectorHistogramMatchesPdf) {
  for (double r : {0.2, 0.5, 1.0}) {
    const double alpha = r * r;
    // The rings span θ from 0 to where 99.9% of the mass lies, the last ring holding the rest.
    const double thetaMax = std::atan(alpha * std::sqrt(0.999 / 0.001));
    const int nt = 16, np = 8, n = 200000;
    std::vector<double> expected(nt * np, 0.0), observed(nt * np, 0.0);
    auto ring = [&](double t) { return std::min(int(t / thetaMax * (nt - 1)), nt - 1); };
    const int fine = 20000;
    for (int i = 0; i < fine; ++i) {  // ∫ pdf over θ by the midpoint rule, shared by the sectors
      const double t = (i + 0.5) * (kPiD / 2) / fine;
      const double mass = brdf::pdfGgxHalfVector(fromAngles(t, 0.0), alpha) * std::sin(t) * (kPiD / 2) / fine;
      for (int p = 0; p < np; ++p) expected[size_t(ring(t) * np + p)] += mass * 2.0 * kPiD / np * n;
    }
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    for (int k = 0; k < n; ++k) {
      const glm::dvec3 h = brdf::sampleGgxHalfVector({uni(rng), uni(rng)}, alpha);
      double phi = std::atan2(h.y, h.x);
      if (phi < 0.0) phi += 2.0 * kPiD;
      observed[size_t(ring(std::acos(std::min(h.z, 1.0))) * np + std::min(int(phi / (2.0 * kPiD) * np), np - 1))] += 1;
    }
    double chi2 = 0.0, total = 0.0;
    for (size_t c = 0; c < expected.size(); ++c) {
      ASSERT_GT(expected[c], 5.0) << "cell " << c;  // χ² needs populated cells
      chi2 += (observed[c] - expected[c]) * (observed[c] - expected[c]) / expected[c];
      total += expected[c];
    }
    EXPECT_NEAR(total, n, 1e-3 * n) << "the pdf does not integrate to 1";
    const double df = nt * np - 1;
    EXPECT_LT(chi2, df + 6.0 * std::sqrt(2.0 * df)) << "roughness " << r;
  }
}

// The reflection pdf integrates over the sphere of l to the share of sampled half vectors that
// face v (v·h > 0; the others mirror v into l whose normalize(l + v) is −h, and a caller weighs
// them 0): the 1/(4|v·h|) Jacobian. Both sides by the midpoint rule, 2000 × 1000 cells;
// roughness ≥ 0.3 so the lobe spans many cells. Tolerance 0.5%.
TEST(BrdfSampling, ReflectionPdfIntegratesToTheHalfVectorsFacingTheView) {
  for (double r : {0.3, 0.6, 1.0})
    for (double nv : {1.0, 0.6, 0.2}) {
      const glm::dvec3 v(std::sqrt(1.0 - nv * nv), 0.0, nv);
      const int nt = 2000, np = 1000;
      const double cell = (kPiD / nt) * (2.0 * kPiD / np);
      double sum = 0.0, facing = 0.0;
      for (int i = 0; i < nt; ++i) {
        const double t = (i + 0.5) * kPiD / nt;
        for (int j = 0; j < np; ++j) {
          const glm::dvec3 w = fromAngles(t, (j + 0.5) * 2.0 * kPiD / np);
          sum += brdf::pdfGgxReflection(w, v, r * r) * std::sin(t);
          if (glm::dot(w, v) > 0.0) facing += brdf::pdfGgxHalfVector(w, r * r) * std::sin(t);
        }
      }
      EXPECT_NEAR(sum * cell, facing * cell, 5e-3) << "roughness " << r << ", n·v " << nv;
      if (nv == 1.0) {
        EXPECT_NEAR(sum * cell, 1.0, 5e-3);  // every half vector faces a normal view
      }
    }
}

// ---- The split-sum DFG table against a brute-force Monte Carlo of the same integrals:
// A = ∫ V D (1 − F_c)(n·l) dl and B = ∫ V D F_c (n·l) dl with light directions uniform over
// the hemisphere (no importance sampling: an independent estimator), 1024 × 1024 jittered
// strata, fixed seed. Roughness ≥ 0.3, where uniform sampling resolves the lobe; tolerance
// 1% relative + 2e-3 (the jittered estimate's spread, measured over seeds, is below 0.3%).
TEST(BrdfDfg, TableMatchesBruteForceMonteCarlo) {
  const brdf::DfgTable table = brdf::computeDfgTable(16, 1024);
  ASSERT_EQ(table.ab.size(), 256u);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (double r : {0.3, 0.6, 1.0})
    for (double nv : {0.9, 0.5, 0.1}) {
      const double alpha = r * r;
      const glm::dvec3 v(std::sqrt(1.0 - nv * nv), 0.0, nv);
      const int side = 1024;
      glm::dvec2 sum(0.0);
      for (int i = 0; i < side; ++i)
        for (int j = 0; j < side; ++j) {
          const double z = (i + uni(rng)) / side, phi = 2.0 * kPiD * (j + uni(rng)) / side;
          const glm::dvec3 l(std::sqrt(1.0 - z * z) * std::cos(phi), std::sqrt(1.0 - z * z) * std::sin(phi), z);
          const glm::dvec3 h = glm::normalize(l + v);
          const double f = brdf::smithVisibility(z, nv, alpha) * brdf::ggxD(h.z, alpha) * z;
          const double fc = brdf::schlick(0.0, glm::dot(v, h));
          sum += glm::dvec2((1.0 - fc) * f, fc * f);
        }
      sum *= 2.0 * kPiD / (double(side) * side);  // uniform hemisphere: pdf 1/(2π)
      const glm::dvec2 direct = brdf::integrateDfg(nv, r, 4096);
      for (int c = 0; c < 2; ++c)
        EXPECT_NEAR(direct[c], sum[c], 0.01 * sum[c] + 2e-3) << "roughness " << r << ", n·v " << nv << ", "
                                                             << "AB"[c];
    }
  // The table's entries are integrateDfg at their centres, and the lookup hits them there.
  const glm::dvec2 at = table.lookup(brdf::DfgTable::coordinate(5, 16), brdf::DfgTable::coordinate(9, 16));
  EXPECT_EQ(at, brdf::integrateDfg(brdf::DfgTable::coordinate(5, 16), brdf::DfgTable::coordinate(9, 16), 1024));
  // F0 = 1 makes A + B the white metal's directional albedo, the furnace test's quantity.
  brdf::MetallicRoughness metal;
  metal.metallic = 1.0, metal.roughness = 0.5;
  const glm::dvec2 ab = brdf::integrateDfg(0.5, 0.5, 4096);
  EXPECT_NEAR(ab.x + ab.y, directionalAlbedo(metal, 0.5).specular.x, 3e-3);
}

// The cosine-averaged terms the bake bounces a metal with (docs/bake.md, "Materials"): a copper
// metal's hemispherical-hemispherical albedo, 2 ∫ E(μ) μ dμ with E the directional albedo of
// brdf::evaluate's specular lobe (importance-sampled above, not the DFG integrator) over 32
// midpoint μ nodes, against F0 · Ā + B̄ per channel; 1% relative (the midpoint rule's error at
// the grazing end is below 0.3%, measured at 64 nodes). A mirror returns everything: Ā + B̄ = 1
// and B̄ = 1/21, Schlick's term averaged over cosine-weighted views.
TEST(BrdfDfg, CosineAverageIsTheLobesHemisphericalAlbedo) {
  for (double r : {0.4, 0.7, 1.0}) {
    brdf::MetallicRoughness copper;
    copper.metallic = 1.0, copper.roughness = r, copper.baseColor = glm::dvec3(0.95, 0.64, 0.54);
    glm::dvec3 mean(0.0);
    const int nodes = 32;
    for (int k = 0; k < nodes; ++k) {
      const double mu = (k + 0.5) / nodes;
      mean += directionalAlbedo(copper, mu).specular * mu * (2.0 / nodes);
    }
    const glm::dvec2 ab = brdf::cosineAveragedDfg(r);
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(copper.baseColor[c] * ab.x + ab.y, mean[c], 0.01 * mean[c]) << "roughness " << r << ", channel " << c;
  }
  const glm::dvec2 mirror = brdf::cosineAveragedDfg(0.0);
  EXPECT_NEAR(mirror.x + mirror.y, 1.0, 2e-3);
  EXPECT_NEAR(mirror.y, 1.0 / 21.0, 2e-3);
  // Between nodes the terms are interpolated, and roughness outside [0, 1] is clamped.
  EXPECT_EQ(brdf::cosineAveragedDfg(1.7), brdf::cosineAveragedDfg(1.0));
  const glm::dvec2 mid = brdf::cosineAveragedDfg(0.5 + 0.5 / 64);
  EXPECT_NEAR(mid.x, 0.5 * (brdf::cosineAveragedDfg(0.5).x + brdf::cosineAveragedDfg(0.5 + 1.0 / 64).x), 1e-12);
}

}  // namespace
}  // namespace prt
