// SH evaluation and the small algebra on coefficients. Conventions: prt/sh.h.
#include "prt/sh.h"

#include <array>
#include <cmath>
#include <cstring>

#include <immintrin.h>

#include "prt/error.h"
#include "prt/math.h"

namespace prt::sh {

namespace {

// Normalisation K_l^m = sqrt((2l+1)/(4π) · (l-m)!/(l+m)!), times √2 for m > 0 (real basis).
struct Norms {
  std::array<std::array<double, kMaxBands>, kMaxBands> k{};
  std::array<std::array<float, kMaxBands>, kMaxBands> f{};  // the same as floats (T(k[l][m]) at T = float)
  Norms() {
    for (int l = 0; l < kMaxBands; ++l)
      for (int m = 0; m <= l; ++m) {
        double ratio = 1.0;  // (l-m)!/(l+m)!
        for (int j = l - m + 1; j <= l + m; ++j) ratio /= j;
        double v = std::sqrt((2.0 * l + 1.0) / (4.0 * kPi) * ratio);
        k[l][m] = m == 0 ? v : std::sqrt(2.0) * v;
        f[l][m] = float(k[l][m]);
      }
  }
};
const Norms kNorms;

// Derivation. Without the Condon-Shortley phase, P_l^m(cos θ) = sin^m θ · Q_l^m(cos θ) with Q a
// polynomial obeying
//   Q_m^m = (2m-1)!!,  Q_{m+1}^m = (2m+1) z Q_m^m,
//   Q_l^m = ((2l-1) z Q_{l-1}^m - (l+m-1) Q_{l-2}^m) / (l-m),
// and sin^m θ cos(mφ) = Re (x+iy)^m, sin^m θ sin(mφ) = Im (x+iy)^m. So every basis function is
// a polynomial in x, y, z: no trigonometry, no division by sin θ, exact at the poles.
// B > 0: bands fixed at compile time (B = bands), so the loops unroll and the norms are
// constants; the same operations in the same order, so the same bits as B = 0.
template <class T, class V, int B = 0>
void evaluateT(int runtimeBands, const V& d, T* out) {
  const int bands = B > 0 ? B : runtimeBands;
  PRT_CHECK(bands >= 1 && bands <= kMaxBands);
  const T x = d.x, y = d.y, z = d.z;
  T cm = 1, sm = 0;  // Re, Im of (x+iy)^m
  T qmm = 1;         // Q_m^m
  for (int m = 0; m < bands; ++m) {
    if (m > 0) {
      T c = cm * x - sm * y;
      sm = cm * y + sm * x;
      cm = c;
      qmm *= T(2 * m - 1);
    }
    T q2 = 0, q1 = qmm;  // Q_{l-2}^m, Q_{l-1}^m as l advances
    for (int l = m; l < bands; ++l) {
      T q;
      if (l == m) {
        q = qmm;
      } else if (l == m + 1) {
        q = T(2 * m + 1) * z * qmm;
      } else {
        q = (T(2 * l - 1) * z * q1 - T(l + m - 1) * q2) / T(l - m);
      }
      if (l > m) {
        q2 = q1;
        q1 = q;
      }
      T kq = T(kNorms.k[l][m]) * q;
      if (m == 0) {
        out[index(l, 0)] = kq;
      } else {
        out[index(l, m)] = kq * cm;
        out[index(l, -m)] = kq * sm;
      }
    }
  }
}

// evaluateT<float, glm::vec3, 3>'s operations, written out, at eight directions (AVX2): the
// loops unrolled with cm = 1, sm = 0, qmm = 1 at the start, every product kept (0 · y is −0 for
// y < 0, and x − (−0) is not x when x = −0), so each lane has the scalar function's bits. The
// eight-lane paths for other band counts evaluate lane by lane.
__attribute__((target("avx2"))) void evaluate8Bands3Avx2(const float* px, const float* py, const float* pz,
                                                         float* out) {
  const __m256 x = _mm256_loadu_ps(px), y = _mm256_loadu_ps(py), z = _mm256_loadu_ps(pz);
  __m256 k[3][3];  // K_l^m as floats (T(kNorms.k[l][m])), converted once (a call converted six)
  for (int l = 0; l < 3; ++l)
    for (int m = 0; m <= l; ++m) k[l][m] = _mm256_broadcast_ss(&kNorms.f[size_t(l)][size_t(m)]);
  const __m256 one = _mm256_set1_ps(1.0f), half = _mm256_set1_ps(0.5f), three = _mm256_set1_ps(3.0f);
  const __m256 zero = _mm256_setzero_ps();
  // m = 0: Q_0^0 = 1, Q_1^0 = (1 · z) · 1, Q_2^0 = ((3 · z) · Q_1^0 − 1 · 1) / 2.
  const __m256 q10 = _mm256_mul_ps(_mm256_mul_ps(one, z), one);
  // "/ 2" as "· 0.5": the same real number, so the same rounded result, without a division.
  const __m256 q20 =
      _mm256_mul_ps(_mm256_sub_ps(_mm256_mul_ps(_mm256_mul_ps(three, z), q10), _mm256_mul_ps(one, one)), half);
  _mm256_storeu_ps(out + 8 * 0, _mm256_mul_ps(k[0][0], one));
  _mm256_storeu_ps(out + 8 * 2, _mm256_mul_ps(k[1][0], q10));
  _mm256_storeu_ps(out + 8 * 6, _mm256_mul_ps(k[2][0], q20));
  // m = 1: (cm, sm) = (1 · x − 0 · y, 1 · y + 0 · x), Q_1^1 = 1 · 1, Q_2^1 = (3 · z) · Q_1^1.
  const __m256 c1 = _mm256_sub_ps(_mm256_mul_ps(one, x), _mm256_mul_ps(zero, y));
  const __m256 s1 = _mm256_add_ps(_mm256_mul_ps(one, y), _mm256_mul_ps(zero, x));
  const __m256 q11 = _mm256_mul_ps(one, one);
  const __m256 k11 = _mm256_mul_ps(k[1][1], q11);
  const __m256 k21 = _mm256_mul_ps(k[2][1], _mm256_mul_ps(_mm256_mul_ps(three, z), q11));
  _mm256_storeu_ps(out + 8 * 3, _mm256_mul_ps(k11, c1));
  _mm256_storeu_ps(out + 8 * 1, _mm256_mul_ps(k11, s1));
  _mm256_storeu_ps(out + 8 * 7, _mm256_mul_ps(k21, c1));
  _mm256_storeu_ps(out + 8 * 5, _mm256_mul_ps(k21, s1));
  // m = 2: (cm, sm) advanced by (x + iy), Q_2^2 = Q_1^1 · 3.
  const __m256 c2 = _mm256_sub_ps(_mm256_mul_ps(c1, x), _mm256_mul_ps(s1, y));
  const __m256 s2 = _mm256_add_ps(_mm256_mul_ps(c1, y), _mm256_mul_ps(s1, x));
  const __m256 k22 = _mm256_mul_ps(k[2][2], _mm256_mul_ps(q11, three));
  _mm256_storeu_ps(out + 8 * 8, _mm256_mul_ps(k22, c2));
  _mm256_storeu_ps(out + 8 * 4, _mm256_mul_ps(k22, s2));
}

}  // namespace

void evaluate8(int bands, const float* x, const float* y, const float* z, float* out) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (bands == 3 && avx2) return evaluate8Bands3Avx2(x, y, z, out);
  float one[kMaxBands * kMaxBands];
  for (int l = 0; l < 8; ++l) {
    evaluate(bands, glm::vec3(x[l], y[l], z[l]), one);
    for (int i = 0; i < bands * bands; ++i) out[8 * i + l] = one[i];
  }
}

int bandOf(int i) {
  int l = static_cast<int>(std::sqrt(static_cast<double>(i)));
  while (l * l > i) --l;
  while ((l + 1) * (l + 1) <= i) ++l;
  return l;
}

void evaluate(int bands, const glm::vec3& d, float* out) {
  switch (bands) {  // the bake's common orders: about half the time of the general loop
    case 2:
      return evaluateT<float, glm::vec3, 2>(bands, d, out);
    case 3:
      return evaluateT<float, glm::vec3, 3>(bands, d, out);
    case 4:
      return evaluateT<float, glm::vec3, 4>(bands, d, out);
    default:
      return evaluateT<float>(bands, d, out);
  }
}
void evaluate(int bands, const glm::dvec3& d, double* out) { evaluateT<double>(bands, d, out); }

std::vector<float> evaluate(int bands, const glm::vec3& d) {
  std::vector<float> out(static_cast<size_t>(numCoeffs(bands)));
  evaluate(bands, d, out.data());
  return out;
}

double clampedCosineFactor(int l) {
  PRT_CHECK_GE(l, 0);
  if (l == 0) return kPi;
  if (l == 1) return 2.0 * kPi / 3.0;
  if (l % 2 == 1) return 0.0;
  // Â_l = 2π (-1)^(l/2-1) / ((l+2)(l-1)) · l! / (2^l ((l/2)!)²)   [Ramamoorthi & Hanrahan 2001]
  double ratio = 1.0;  // l! / (2^l ((l/2)!)²) = C(l, l/2) / 2^l
  for (int j = 1; j <= l / 2; ++j) ratio *= double(l / 2 + j) / double(j);
  ratio /= std::ldexp(1.0, l);
  double sign = ((l / 2 - 1) % 2 == 0) ? 1.0 : -1.0;
  return 2.0 * kPi * sign / double((l + 2) * (l - 1)) * ratio;
}

ShRgb& ShRgb::operator+=(const ShRgb& o) {
  PRT_CHECK_EQ(bands, o.bands);
  for (size_t i = 0; i < c.size(); ++i) c[i] += o.c[i];
  return *this;
}

ShRgb& ShRgb::operator*=(const glm::vec3& s) {
  for (auto& v : c) v *= s;
  return *this;
}

ShRgb& ShRgb::operator*=(float s) {
  for (auto& v : c) v *= s;
  return *this;
}

ShRgb resize(const ShRgb& in, int bands) {
  ShRgb out(bands);
  int n = std::min(in.size(), out.size());
  for (int i = 0; i < n; ++i) out.c[i] = in.c[i];
  return out;
}

glm::vec3 dot(const glm::vec3* t, const glm::vec3* l, int n) {
  glm::vec3 s(0.0f);
  for (int i = 0; i < n; ++i) s += t[i] * l[i];
  return s;
}

glm::vec3 dot(const ShRgb& t, const ShRgb& l) {
  PRT_CHECK_EQ(t.bands, l.bands);
  return dot(t.c.data(), l.c.data(), t.size());
}

glm::vec3 reconstruct(const ShRgb& c, const glm::vec3& d) {
  float y[kMaxBands * kMaxBands];
  evaluate(c.bands, d, y);
  glm::vec3 s(0.0f);
  for (int i = 0; i < c.size(); ++i) s += c.c[i] * y[i];
  return s;
}

glm::vec3 irradiance(const ShRgb& c, const glm::vec3& n) {
  float y[kMaxBands * kMaxBands];
  evaluate(c.bands, n, y);
  glm::vec3 s(0.0f);
  for (int l = 0; l < c.bands; ++l) {
    float a = static_cast<float>(clampedCosineFactor(l));
    for (int m = -l; m <= l; ++m) s += a * c.c[index(l, m)] * y[index(l, m)];
  }
  return s;
}

void convolveClampedCosine(ShRgb& c) {
  for (int l = 0; l < c.bands; ++l) {
    float a = static_cast<float>(clampedCosineFactor(l));
    for (int m = -l; m <= l; ++m) c.c[index(l, m)] *= a;
  }
}

}  // namespace prt::sh
