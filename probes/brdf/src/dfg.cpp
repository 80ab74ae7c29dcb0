// The split-sum DFG table (prt/brdf.h [5, 6]): (A, B) per (n·v, roughness) by importance
// sampling GGX half vectors on a Hammersley set.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "prt/brdf.h"
#include "prt/error.h"

namespace prt::brdf {

namespace {

/// The radical inverse in base 2 (van der Corput), the second Hammersley coordinate.
double radicalInverse2(uint32_t i) {
  i = (i << 16u) | (i >> 16u);
  i = ((i & 0x55555555u) << 1u) | ((i & 0xAAAAAAAAu) >> 1u);
  i = ((i & 0x33333333u) << 2u) | ((i & 0xCCCCCCCCu) >> 2u);
  i = ((i & 0x0F0F0F0Fu) << 4u) | ((i & 0xF0F0F0F0u) >> 4u);
  i = ((i & 0x00FF00FFu) << 8u) | ((i & 0xFF00FF00u) >> 8u);
  return double(i) * 0x1p-32;
}

}  // namespace

glm::dvec2 integrateDfg(double nDotV, double roughness, int samples) {
  PRT_CHECK_GT(samples, 0);
  const double nv = std::clamp(nDotV, 1e-4, 1.0);
  const double r = std::max(roughness, kMinRoughness), alpha = r * r;
  const glm::dvec3 v(std::sqrt(1.0 - nv * nv), 0.0, nv);
  glm::dvec2 sum(0.0);
  for (int i = 0; i < samples; ++i) {
    const glm::dvec2 u((i + 0.5) / samples, radicalInverse2(uint32_t(i)));
    const glm::dvec3 h = sampleGgxHalfVector(u, alpha);
    const double vh = glm::dot(v, h);
    const glm::dvec3 l = 2.0 * vh * h - v;
    if (l.z <= 0.0 || vh <= 0.0) continue;
    // f_spec (n·l) / pdf_l = V D (n·l) · 4 (v·h) / (D (n·h)): D cancels.
    const double w = 4.0 * smithVisibility(l.z, nv, alpha) * l.z * vh / h.z;
    const double fc = schlick(0.0, vh);  // (1 − v·h)⁵
    sum += glm::dvec2((1.0 - fc) * w, fc * w);
  }
  return sum / double(samples);
}

DfgTable computeDfgTable(int size, int samples) {
  PRT_CHECK_GT(size, 1);
  DfgTable t;
  t.size = size;
  t.ab.resize(size_t(size) * size_t(size));
  for (int row = 0; row < size; ++row)
    for (int column = 0; column < size; ++column)
      t.ab[size_t(row) * size_t(size) + size_t(column)] =
          integrateDfg(DfgTable::coordinate(column, size), DfgTable::coordinate(row, size), samples);
  return t;
}

glm::dvec2 cosineAveragedDfg(double roughness) {
  constexpr int kRoughness = 65, kCosines = 64, kSamples = 512;
  static const std::vector<glm::dvec2> table = [] {
    std::vector<glm::dvec2> t(kRoughness);
    for (int r = 0; r < kRoughness; ++r) {
      glm::dvec2 sum(0.0);
      for (int c = 0; c < kCosines; ++c) {
        const double mu = (c + 0.5) / kCosines;
        sum += integrateDfg(mu, double(r) / (kRoughness - 1), kSamples) * mu;
      }
      t[size_t(r)] = 2.0 * sum / double(kCosines);
    }
    return t;
  }();
  const double x = std::isfinite(roughness) ? std::clamp(roughness, 0.0, 1.0) * (kRoughness - 1) : kRoughness - 1;
  const int i = std::min(int(x), kRoughness - 2);
  const double f = x - i;
  return table[size_t(i)] * (1.0 - f) + table[size_t(i) + 1] * f;
}

glm::dvec2 DfgTable::lookup(double nDotV, double roughness) const {
  PRT_CHECK_GT(size, 1);
  auto axis = [&](double x, int& i0, double& f) {
    const double s = std::clamp(x * size - 0.5, 0.0, double(size - 1));
    i0 = std::min(int(s), size - 2);
    f = s - i0;
  };
  int c, r;
  double fc, fr;
  axis(nDotV, c, fc);
  axis(roughness, r, fr);
  auto at = [&](int row, int column) { return ab[size_t(row) * size_t(size) + size_t(column)]; };
  const glm::dvec2 lo = at(r, c) * (1.0 - fc) + at(r, c + 1) * fc;
  const glm::dvec2 hi = at(r + 1, c) * (1.0 - fc) + at(r + 1, c + 1) * fc;
  return lo * (1.0 - fr) + hi * fr;
}

}  // namespace prt::brdf
