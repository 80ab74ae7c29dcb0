// Sampling helpers, each as a triplet sample / pdf / invert (pbrt-v4 util/sampling.h), tested
// against each other in tests/test_bake.cpp and, by χ² fit to the pdf, tests/test_sampling.cpp.
#pragma once

#include <cmath>
#include <cstdint>

#include <glm/glm.hpp>

#include "prt/math.h"

namespace prt::bake {

/// SplitMix64: a 64-bit mixer, for per-vertex seeds that do not depend on thread scheduling.
inline uint64_t splitMix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

/// First two dimensions of the Sobol sequence, digit-scrambled by XOR with `scramble` (which
/// keeps the (0, m, 2)-net property of every power-of-two prefix). Values in [0, 1).
/// sobol0Bits and sobol1Bits are the same values as 24-bit integers (value = bits · 2⁻²⁴), and
/// sobol0Point and sobol1Point the unscrambled 32-bit points they are cut from. Both dimensions
/// are linear over GF(2): the point of i XOR j is the XOR of their points.
constexpr uint32_t sobol0Point(uint32_t i) {  // the index's bits reversed
  uint32_t r = i;
  r = (r << 16) | (r >> 16);
  r = ((r & 0x00ff00ffu) << 8) | ((r & 0xff00ff00u) >> 8);
  r = ((r & 0x0f0f0f0fu) << 4) | ((r & 0xf0f0f0f0u) >> 4);
  r = ((r & 0x33333333u) << 2) | ((r & 0xccccccccu) >> 2);
  return ((r & 0x55555555u) << 1) | ((r & 0xaaaaaaaau) >> 1);
}
inline uint32_t sobol0Bits(uint32_t i, uint32_t scramble) { return (sobol0Point(i) ^ scramble) >> 8; }
inline float sobol0(uint32_t i, uint32_t scramble) { return float(sobol0Bits(i, scramble)) * 0x1p-24f; }
// The second dimension's generator matrix applied a byte of the index at a time: entry
// [j][b] is the XOR of the direction numbers v_k (v_0 = 2³¹, v_k = v_{k−1} ^ (v_{k−1} >> 1)) of
// the bits k = 8j… of b. The same values as a bit-by-bit loop, without its data-dependent
// trip count (4 KiB, built at compile time).
struct Sobol1Table {
  uint32_t t[4][256];
  constexpr Sobol1Table() : t{} {
    uint32_t v[32] = {};
    v[0] = 1u << 31;
    for (int k = 1; k < 32; ++k) v[k] = v[k - 1] ^ (v[k - 1] >> 1);
    for (int j = 0; j < 4; ++j)
      for (uint32_t b = 0; b < 256; ++b) {
        uint32_t r = 0;
        for (int k = 0; k < 8; ++k)
          if (b >> k & 1u) r ^= v[8 * j + k];
        t[j][b] = r;
      }
  }
};
inline constexpr Sobol1Table kSobol1{};

constexpr uint32_t sobol1Point(uint32_t i) {
  return kSobol1.t[0][i & 0xffu] ^ kSobol1.t[1][(i >> 8) & 0xffu] ^ kSobol1.t[2][(i >> 16) & 0xffu] ^
         kSobol1.t[3][i >> 24];
}
inline uint32_t sobol1Bits(uint32_t i, uint32_t scramble) { return (sobol1Point(i) ^ scramble) >> 8; }
inline float sobol1(uint32_t i, uint32_t scramble) { return float(sobol1Bits(i, scramble)) * 0x1p-24f; }

/// sin a and cos a for |a| ≤ π/4, by the minimax polynomials of Cephes' sinf and cosf (within
/// 1.2e-7 of both): additions and multiplications only, so that a loop of them vectorises and
/// gives the same bits in every lane and on every machine, where libm's sincosf is a call per
/// angle, with no promise about its last bit.
/// The coefficients (also the probe bake's vector kernels'): sin a = a + a·a² (S1 + a² (S2 + a² S3)),
/// cos a = 1 − a²/2 + a⁴ (C1 + a² (C2 + a² C3)).
inline constexpr float kSinS1 = -1.6666654611e-1f, kSinS2 = 8.3321608736e-3f, kSinS3 = -1.9515295891e-4f;
inline constexpr float kCosC1 = 4.166664568298827e-2f, kCosC2 = -1.388731625493765e-3f, kCosC3 = 2.443315711809948e-5f;
inline void sinCosQuarter(float a, float& s, float& c) {
  const float a2 = a * a;
  s = a + a * a2 * (kSinS1 + a2 * (kSinS2 + a2 * kSinS3));
  c = 1.0f - 0.5f * a2 + a2 * a2 * (kCosC1 + a2 * (kCosC2 + a2 * kCosC3));
}

/// Shirley-Chiu concentric map from the unit square to the unit disk (area preserving).
inline glm::vec2 sampleConcentricDisk(const glm::vec2& u) {
  glm::vec2 o = 2.0f * u - 1.0f;
  if (o.x == 0.0f && o.y == 0.0f) return {0.0f, 0.0f};
  // θ = π/4 · minor/major in the wedge of the larger coordinate, |π/4 · minor/major| ≤ π/4:
  // sinCosQuarter without a range reduction; the top and bottom wedges (θ = π/2 − π/4 · x/y)
  // swap its sine and cosine.
  const bool wide = std::fabs(o.x) > std::fabs(o.y);
  const float r = wide ? o.x : o.y;
  const float a = (kPiF / 4.0f) * (wide ? o.y / o.x : o.x / o.y);
  float s, c;
  sinCosQuarter(a, s, c);
  return wide ? glm::vec2(r * c, r * s) : glm::vec2(r * s, r * c);
}
inline glm::vec2 invertConcentricDisk(const glm::vec2& p) {
  float r = std::sqrt(p.x * p.x + p.y * p.y);
  float phi = std::atan2(p.y, p.x);
  if (phi < -kPiF / 4.0f) phi += 2.0f * kPiF;  // phi in [-π/4, 7π/4)
  float a, b;
  if (phi < kPiF / 4.0f) {  // right wedge: r = a, theta = π/4 · b/a
    a = r;
    b = phi * a / (kPiF / 4.0f);
  } else if (phi < 3.0f * kPiF / 4.0f) {  // top: r = b, theta = π/2 - π/4 · a/b
    b = r;
    a = (kPiF / 2.0f - phi) * b / (kPiF / 4.0f);
  } else if (phi < 5.0f * kPiF / 4.0f) {  // left: r = -a = |a|
    a = -r;
    b = (phi - kPiF) * a / (kPiF / 4.0f);
  } else {  // bottom: r = -b
    b = -r;
    a = (kPiF / 2.0f - (phi - kPiF)) * b / (kPiF / 4.0f);
  }
  return (glm::vec2(a, b) + 1.0f) * 0.5f;
}

/// Cosine-weighted direction about +Z (Malley's method), pdf cos θ / π.
inline glm::vec3 sampleCosineHemisphere(const glm::vec2& u) {
  glm::vec2 d = sampleConcentricDisk(u);
  float z = std::sqrt(std::max(0.0f, 1.0f - d.x * d.x - d.y * d.y));
  return {d.x, d.y, z};
}
inline float cosineHemispherePdf(float cosTheta) { return cosTheta > 0.0f ? cosTheta / kPiF : 0.0f; }
inline glm::vec2 invertCosineHemisphere(const glm::vec3& w) { return invertConcentricDisk({w.x, w.y}); }

/// Uniform direction on the sphere, pdf 1 / (4π).
inline glm::vec3 sampleUniformSphere(const glm::vec2& u) {
  float z = 1.0f - 2.0f * u.x;
  float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  float phi = 2.0f * kPiF * u.y;
  return {r * std::cos(phi), r * std::sin(phi), z};
}
inline float uniformSpherePdf() { return 1.0f / (4.0f * kPiF); }

/// sampleUniformSphere of the point (bx · 2⁻²⁴, by · 2⁻²⁴), bx, by < 2²⁴ (sobol0Bits,
/// sobol1Bits), within 2e-7 of it: φ = 2π · by · 2⁻²⁴ is split exactly, in integers, into its
/// quarter turn q and a remainder of at most π/4 (sinCosQuarter). Branch-free: the directions of
/// a stream are computed in one vectorised loop (the probe bake's rays).
inline glm::vec3 uniformSphereFromBits(uint32_t bx, uint32_t by) {
  const float z = 1.0f - 2.0f * (float(bx) * 0x1p-24f);
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  const uint32_t q = (by + (1u << 21)) >> 22;  // the nearest quarter turn, 0 … 4
  const float a = float(int32_t(by) - int32_t(q << 22)) * (0x1p-22f * 0.5f * kPiF);
  float s, c;
  sinCosQuarter(a, s, c);
  const uint32_t k = q & 3u;  // rotate (cos a, sin a) by k quarter turns
  const float cx = k == 0 ? c : k == 1 ? -s : k == 2 ? -c : s;
  const float sy = k == 0 ? s : k == 1 ? c : k == 2 ? -s : -c;
  return {r * cx, r * sy, z};
}
inline glm::vec2 invertUniformSphere(const glm::vec3& w) {
  float phi = std::atan2(w.y, w.x);
  if (phi < 0.0f) phi += 2.0f * kPiF;
  return {(1.0f - w.z) * 0.5f, phi / (2.0f * kPiF)};
}

/// Orthonormal frame about a unit normal (Duff et al. 2017, branchless).
struct Frame {
  glm::vec3 t, b, n;
  static Frame fromNormal(const glm::vec3& n) {
    float sign = std::copysign(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float bb = n.x * n.y * a;
    return {{1.0f + sign * n.x * n.x * a, sign * bb, -sign * n.x}, {bb, sign + n.y * n.y * a, -n.y}, n};
  }
  glm::vec3 toWorld(const glm::vec3& v) const { return v.x * t + v.y * b + v.z * n; }
  glm::vec3 toLocal(const glm::vec3& v) const { return {glm::dot(v, t), glm::dot(v, b), glm::dot(v, n)}; }
};

}  // namespace prt::bake
