// Distant lights projected to SH: equirectangular maps, disks (caps), suns, uniform skies.
// Conventions: prt/light.h, prt/sh.h; docs/lights.md has the derivations in one place.
#include "prt/light.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prt/error.h"
#include "prt/math.h"

namespace prt {

namespace {

void checkBands(int bands) {
  if (bands < 1 || bands > sh::kMaxBands) throw Error(cat("SH bands must be 1 to ", sh::kMaxBands, ", got ", bands));
}

glm::dvec3 unitDirection(const glm::dvec3& d, const char* what) {
  const double len = glm::length(d);
  if (!std::isfinite(len) || len < 1e-12)
    throw Error(cat(what, " direction (", d.x, ", ", d.y, ", ", d.z, ") is not a direction"));
  return d / len;
}

sh::ShRgb toShRgb(int bands, const std::vector<glm::dvec3>& c) {
  sh::ShRgb out(bands);
  for (int i = 0; i < out.size(); ++i) out.c[i] = glm::vec3(c[i]);
  return out;
}

// Note 1: the SH of a cap. A function of the angle to an axis d alone, g(ω) = g(d·ω), has
// coefficients (Funk-Hecke) ∫ g(d·ω) y_lm(ω) dω = λ_l y_lm(d), λ_l = 2π ∫₋₁¹ g(t) P_l(t) dt.
// For a cap of angular radius r and radiance L, g = L on t >= cos r, so
//   λ_l = 2π L ∫_{cos r}^1 P_l(t) dt,
// which equals 2π L (1 - cos r) for l = 0 and 2π L (P_{l-1}(cos r) - P_{l+1}(cos r)) / (2l+1)
// for l >= 1 (from (2l+1) P_l = P'_{l+1} - P'_{l-1} and P_l(1) = 1).
//
// Note 2: evaluating it without cancellation. For a small cap P_{l-1}(cos r) - P_{l+1}(cos r) is
// a difference of two numbers near 1, and 1 - cos r itself vanishes in double below r ≈ 1e-8,
// so a sun of small radius would lose every digit. Instead write s = 1 - cos r = 2 sin²(r/2)
// (exact to rounding) and use the hypergeometric form of P_l about t = 1,
//   P_l(1 - s) = Σ_{k=0}^{l} (-1)^k C(l+k, k) C(l, k) (s/2)^k,
// whose integral over s is
//   ∫_{1-s}^1 P_l(t) dt = Σ_{k=0}^{l} (-1)^k C(l+k, k) C(l, k) 2^{-k} s^{k+1} / (k+1).
// Every term is O(s^{k+1}), so small caps lose nothing; for s up to 2 (r = π) the terms stay
// below 5544 for l <= 7, so the absolute error stays below ~1e-12.
double capLegendreIntegral(int l, double s) {
  double sum = 0.0;
  double binomLk = 1.0;  // C(l+k, k)
  double binomL = 1.0;   // C(l, k)
  double sPow = s;       // s^{k+1} / 2^k
  for (int k = 0; k <= l; ++k) {
    if (k > 0) {
      binomLk = binomLk * (l + k) / k;
      binomL = binomL * (l - k + 1) / k;
      sPow *= s / 2.0;
    }
    const double term = binomLk * binomL * sPow / (k + 1);
    sum += (k % 2 == 0) ? term : -term;
  }
  return sum;
}

// λ_l / L = 2π ∫_{cos r}^1 P_l(t) dt for l < bands (Note 1).
std::array<double, sh::kMaxBands> capFactors(int bands, double radius) {
  const double halfSin = std::sin(radius / 2.0);
  const double s = 2.0 * halfSin * halfSin;
  std::array<double, sh::kMaxBands> k{};
  for (int l = 0; l < bands; ++l) k[l] = 2.0 * kPi * capLegendreIntegral(l, s);
  return k;
}

// c_lm = factor_l · radiance · y_lm(d): the SH of any zonal function about d.
sh::ShRgb zonal(int bands, const glm::dvec3& d, const std::array<double, sh::kMaxBands>& factor,
                const glm::dvec3& radiance) {
  double y[sh::kMaxBands * sh::kMaxBands];
  sh::evaluate(bands, d, y);
  std::vector<glm::dvec3> c(static_cast<size_t>(sh::numCoeffs(bands)));
  for (int l = 0; l < bands; ++l)
    for (int m = -l; m <= l; ++m) c[sh::index(l, m)] = factor[l] * y[sh::index(l, m)] * radiance;
  return toShRgb(bands, c);
}

}  // namespace

glm::dvec3 equirectDirection(double u, double v) {
  // Inverse of u = 0.5 + φ / 2π with φ = atan2(z, x), v = θ / π with θ the angle from +Y.
  const double phi = 2.0 * kPi * (u - 0.5);
  const double theta = kPi * v;
  const double sinTheta = std::sin(theta);
  return {sinTheta * std::cos(phi), std::cos(theta), sinTheta * std::sin(phi)};
}

glm::dvec2 equirectUv(const glm::dvec3& d) {
  // Clamped so a direction a rounding error longer than 1 still maps to the top or bottom row.
  const double y = glm::clamp(d.y, -1.0, 1.0);
  return {0.5 + std::atan2(d.z, d.x) / (2.0 * kPi), std::acos(y) / kPi};
}

glm::dvec3 sampleEquirect(const ImageRgb& equirect, const glm::dvec3& d) {
  const int w = equirect.width, h = equirect.height;
  PRT_CHECK(w > 0 && h > 0);
  const glm::dvec2 uv = equirectUv(d);
  const double x = uv.x * w - 0.5, y = uv.y * h - 0.5;
  const double x0 = std::floor(x), y0 = std::floor(y);
  const double fx = x - x0, fy = y - y0;
  auto wrap = [w](double i) { return int(((long long)i % w + w) % w); };
  auto clampRow = [h](double j) { return int(std::clamp(j, 0.0, double(h - 1))); };
  const int xa = wrap(x0), xb = wrap(x0 + 1.0), ya = clampRow(y0), yb = clampRow(y0 + 1.0);
  auto at = [&](int px, int py) { return glm::dvec3(equirect.at(px, py)); };
  return (1.0 - fy) * ((1.0 - fx) * at(xa, ya) + fx * at(xb, ya)) + fy * ((1.0 - fx) * at(xa, yb) + fx * at(xb, yb));
}

double equirectPixelSolidAngle(int row, int width, int height) {
  PRT_CHECK(width > 0 && height > 0 && row >= 0 && row < height);
  // (2π/W)(cos θ₀ - cos θ₁) written as (2π/W) · 2 sin θ_c sin(Δθ/2), θ_c = π(row + ½)/H, which
  // does not cancel near the poles.
  return (2.0 * kPi / width) * 2.0 * std::sin(kPi * ((row + 0.5) / height)) * std::sin(kPi / (2.0 * height));
}

sh::ShRgb projectEnvironment(const ImageRgb& equirect, int bands) {
  checkBands(bands);
  const int w = equirect.width, h = equirect.height;
  PRT_CHECK_EQ(equirect.pixels.size(), static_cast<size_t>(w) * h);
  if (w <= 0 || h <= 0) throw Error(cat("environment map of ", w, "x", h, " pixels is empty"));
  const int n = sh::numCoeffs(bands);

  // Each row's sum in double, in its own slot; the rows are then added in order, so the result
  // does not depend on how TBB splits the rows among threads.
  std::vector<glm::dvec3> rows(static_cast<size_t>(h) * n, glm::dvec3(0.0));
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& range) {
    double y[sh::kMaxBands * sh::kMaxBands];
    for (int row = range.begin(); row != range.end(); ++row) {
      glm::dvec3* acc = &rows[static_cast<size_t>(row) * n];
      const double v = (row + 0.5) / h;
      for (int x = 0; x < w; ++x) {
        sh::evaluate(bands, equirectDirection((x + 0.5) / w, v), y);
        const glm::dvec3 radiance(equirect.at(x, row));
        for (int i = 0; i < n; ++i) acc[i] += radiance * y[i];
      }
      const double dOmega = equirectPixelSolidAngle(row, w, h);
      for (int i = 0; i < n; ++i) acc[i] *= dOmega;
    }
  });

  std::vector<glm::dvec3> c(static_cast<size_t>(n), glm::dvec3(0.0));
  for (int row = 0; row < h; ++row)
    for (int i = 0; i < n; ++i) c[i] += rows[static_cast<size_t>(row) * n + i];
  return toShRgb(bands, c);
}

sh::ShRgb projectDiskRadiance(int bands, const glm::dvec3& toLight, double radius, const glm::dvec3& radiance) {
  checkBands(bands);
  if (!(radius > 0.0 && radius <= kPi)) throw Error(cat("disk radius ", radius, " rad is outside (0, π]"));
  return zonal(bands, unitDirection(toLight, "disk"), capFactors(bands, radius), radiance);
}

sh::ShRgb projectSun(int bands, const glm::dvec3& toLight, double radius, const glm::dvec3& irradiance) {
  checkBands(bands);
  if (!(radius >= 0.0 && radius < kPi / 2.0)) throw Error(cat("sun radius ", radius, " rad is outside [0, π/2)"));
  const glm::dvec3 d = unitDirection(toLight, "sun");
  // A disk of radiance L and radius r < π/2 seen by a surface facing it gives
  //   E = ∫_cap L cos θ dω = 2π L ∫_{cos r}^1 t dt = π L sin² r,
  // so L = E / (π sin² r). The cap factors of Note 1 times L are then E · 2 I_l(s) / sin² r,
  // I_l = ∫_{cos r}^1 P_l. As r -> 0, I_l(s) -> s = 1 - cos r (P_l ≈ 1 on the cap) and
  // s / sin² r = 1 / (1 + cos r) -> 1/2, so every factor tends to E: the delta's coefficients
  // E · y_lm(d), which r = 0 uses directly.
  //
  // Note 3: small radii. Band l deviates from the delta by a factor 1 + r²/4 − l(l+1) r²/8 +
  // O(r⁴), at most 7 r² for l <= 7: 7e-12 below kPointSunRadians = 1e-6, far under float's
  // rounding (6e-8), so the delta is used there. The disk formula would hold much lower (s and
  // sin² r keep their relative precision until they underflow near r = 1e-154, where s / sin² r
  // becomes 0/0), but gains nothing.
  std::array<double, sh::kMaxBands> factor{};
  if (radius < kPointSunRadians) {
    factor.fill(1.0);
  } else {
    const double halfSin = std::sin(radius / 2.0);
    const double s = 2.0 * halfSin * halfSin;
    const double sin2 = std::sin(radius) * std::sin(radius);
    for (int l = 0; l < bands; ++l) factor[l] = 2.0 * capLegendreIntegral(l, s) / sin2;
  }
  return zonal(bands, d, factor, irradiance);
}

glm::dvec3 DirectLight::radiance() const {
  if (radius < kPointSunRadians) return glm::dvec3(0.0);
  return irradiance / (kPi * std::sin(radius) * std::sin(radius));
}

sh::ShRgb DirectLight::project(int bands) const { return projectSun(bands, direction, radius, irradiance); }

// Note 4: the irradiance of a cap clipped by a surface's horizon. A cap of angular radius r
// around d, of radiance L, seen from a surface whose normal makes angle θ with d:
//   fully above the horizon (θ ≤ π/2 − r): E = π L sin² r cos θ (Note 1 of projectSun);
//   fully below (θ ≥ π/2 + r): 0;
//   straddling it: E = L [ (cos θ acos y − x sin θ √(1 − y²)) sin² r + atan(sin θ √(1 − y²) / x) ],
//   x = √(1/sin² r − 1) = cot r, y = −x cot θ,
// the form factor of a sphere to a tilted differential area (Snyder, "Area light sources for
// real-time graphics", 1996; the form Lagarde & de Rousiers use in "Moving Frostbite to PBR",
// 2014). Divided by π sin² r it is the share of E(facing) that arrives. The test checks it
// against quadrature over the cap.
double directCosineFactor(const DirectLight& light, const glm::dvec3& n) {
  const double cosTheta = std::clamp(glm::dot(n, light.direction), -1.0, 1.0);
  const double r = light.radius;
  if (r < kPointSunRadians) return std::max(cosTheta, 0.0);
  const double sin2 = std::sin(r) * std::sin(r);
  if (cosTheta * cosTheta > sin2) return std::max(cosTheta, 0.0);  // wholly above (or below) the horizon
  const double sinTheta = std::sqrt(std::max(0.0, 1.0 - cosTheta * cosTheta));
  const double x = std::sqrt(std::max(0.0, 1.0 / sin2 - 1.0));
  const double y = std::clamp(-x * cosTheta / std::max(sinTheta, 1e-300), -1.0, 1.0);
  const double sy = sinTheta * std::sqrt(std::max(0.0, 1.0 - y * y));
  const double e = (cosTheta * std::acos(y) - x * sy) * sin2 + std::atan2(sy, x);
  return std::clamp(e / (kPi * sin2), 0.0, 1.0);
}

sh::ShRgb projectUniform(int bands, const glm::dvec3& radiance) {
  checkBands(bands);
  // ∫ L y_0 dω = L · 4π · 1/(2√π) = 2√π L; every other y_i integrates to 0 over the sphere.
  sh::ShRgb out(bands);
  out.c[0] = glm::vec3(2.0 * std::sqrt(kPi) * radiance);
  return out;
}

}  // namespace prt
