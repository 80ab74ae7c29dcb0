// Exact rotation of real SH coefficients for every band. Conventions: prt/sh.h.
//
// Notes on the method (Ivanic & Ruedenberg [3], with the 1998 errata):
// 1. Rotation never mixes bands, so D(R) is block diagonal with one (2l+1)² block per band.
// 2. Band 0 is invariant: D⁰ = 1.
// 3. Band 1 is the linear functions y_{1,m} ∝ (y, z, x) for m = -1, 0, 1. If f(ω) = a·ω then
//    f(R⁻¹ω) = a·(Rᵀω) = (R a)·ω, so D¹ is R itself with rows and columns permuted to (y, z, x).
//    Without the Condon-Shortley phase there is no sign flip on m = ±1 (google's
//    spherical-harmonics library, which keeps the phase, negates those rows and columns).
// 4. Band l follows from D¹ and D^{l-1}: D^l_{mn} = u U + v V + w W, with the coefficients
//    u, v, w of [3] Table 1 and the functions U, V, W of Table 2 built from the helper P below.
//    The recurrence commutes with the sign change y_{lm} -> (-1)^m y_{lm} (every term keeps the
//    parity of m + n), so it serves our phase-free basis unchanged; the tests check this by
//    rotating band-limited functions and projecting them again.
// 5. The errata: for m < 0, V = P¹_{m+1,n} (1 - δ_{m,-1}) + P⁻¹_{-m-1,n} √(1 + δ_{m,-1}),
//    the mirror image of the m > 0 case; the printed tables get these Kronecker factors wrong
//    (google/spherical-harmonics derives the same correction by hand).
#include "prt/sh.h"

#include <cmath>
#include <cstdlib>

#include "prt/error.h"
#include "prt/math.h"

namespace prt::sh {

namespace {

// Read access to a band block with centred indices -l..l, as [3] writes them.
class Block {
 public:
  Block(int l, const std::vector<double>& a) : l_(l), a_(a) {}
  double operator()(int m, int n) const { return a_[(m + l_) * (2 * l_ + 1) + (n + l_)]; }

 private:
  int l_;
  const std::vector<double>& a_;
};

double delta(int a, int b) { return a == b ? 1.0 : 0.0; }

// P^i_{a,b} of [3]: one element of D¹ times one of D^{l-1}; columns b = ±l wrap around the
// edge of D^{l-1} through the ±1 columns of D¹.
double helperP(int i, int a, int b, int l, const Block& r1, const Block& rPrev) {
  if (b == l) return r1(i, 1) * rPrev(a, l - 1) - r1(i, -1) * rPrev(a, -l + 1);
  if (b == -l) return r1(i, 1) * rPrev(a, -l + 1) + r1(i, -1) * rPrev(a, l - 1);
  return r1(i, 0) * rPrev(a, b);
}

// Block of band l >= 2 from band 1 and band l-1.
std::vector<double> bandBlock(int l, const Block& r1, const Block& rPrev) {
  const int size = 2 * l + 1;
  std::vector<double> out(static_cast<size_t>(size) * size);
  for (int m = -l; m <= l; ++m) {
    const int am = std::abs(m);
    const double d0 = delta(m, 0);
    for (int n = -l; n <= l; ++n) {
      const double denom = std::abs(n) == l ? 2.0 * l * (2.0 * l - 1.0) : double((l + n) * (l - n));
      double sum = 0.0;
      // u vanishes exactly when |m| = l, where U would index outside D^{l-1}.
      if (am < l) {
        double u = std::sqrt(double((l + m) * (l - m)) / denom);
        sum += u * helperP(0, m, n, l, r1, rPrev);
      }
      {
        double v = 0.5 * std::sqrt((1.0 + d0) * (l + am - 1.0) * (l + am) / denom) * (1.0 - 2.0 * d0);
        double bigV;
        if (m == 0) {
          bigV = helperP(1, 1, n, l, r1, rPrev) + helperP(-1, -1, n, l, r1, rPrev);
        } else if (m > 0) {
          bigV = helperP(1, m - 1, n, l, r1, rPrev) * std::sqrt(1.0 + delta(m, 1)) -
                 helperP(-1, -m + 1, n, l, r1, rPrev) * (1.0 - delta(m, 1));
        } else {
          bigV = helperP(1, m + 1, n, l, r1, rPrev) * (1.0 - delta(m, -1)) +
                 helperP(-1, -m - 1, n, l, r1, rPrev) * std::sqrt(1.0 + delta(m, -1));
        }
        sum += v * bigV;
      }
      // w vanishes exactly when |m| >= l-1 (and for m = 0), where W would index outside.
      if (m != 0 && am < l - 1) {
        double w = -0.5 * std::sqrt((l - am - 1.0) * (l - am) / denom);
        double bigW = m > 0 ? helperP(1, m + 1, n, l, r1, rPrev) + helperP(-1, -m - 1, n, l, r1, rPrev)
                            : helperP(1, m - 1, n, l, r1, rPrev) - helperP(-1, -m + 1, n, l, r1, rPrev);
        sum += w * bigW;
      }
      out[(m + l) * size + (n + l)] = sum;
    }
  }
  return out;
}

}  // namespace

Rotation::Rotation(int bands, const glm::dmat3& R) : bands_(bands) {
  PRT_CHECK(bands >= 1 && bands <= kMaxBands);
  // A scaled or skewed matrix would silently give a non-orthogonal D; 1e-4 admits rotations
  // that went through single precision.
  const glm::dmat3 rrt = R * glm::transpose(R);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) PRT_CHECK_LT(std::abs(rrt[i][j] - (i == j ? 1.0 : 0.0)), 1e-4);
  PRT_CHECK_GT(glm::determinant(R), 0.0);

  blocks_.reserve(static_cast<size_t>(bands));
  blocks_.push_back({1.0});
  if (bands == 1) return;

  // Row/column k = m + 1 of D¹ is Cartesian axis perm[k]: (y, z, x). glm is column-major,
  // so R(i, j) = R[j][i].
  const int perm[3] = {1, 2, 0};
  std::vector<double> b1(9);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) b1[r * 3 + c] = R[perm[c]][perm[r]];
  blocks_.push_back(std::move(b1));

  for (int l = 2; l < bands; ++l) {
    Block r1(1, blocks_[1]);
    Block rPrev(l - 1, blocks_[l - 1]);
    blocks_.push_back(bandBlock(l, r1, rPrev));
  }
}

void Rotation::apply(const float* in, float* out) const {
  for (int l = 0; l < bands_; ++l) {
    const int size = 2 * l + 1;
    const int base = l * l;
    const std::vector<double>& b = blocks_[l];
    for (int r = 0; r < size; ++r) {
      double s = 0.0;
      for (int c = 0; c < size; ++c) s += b[r * size + c] * in[base + c];
      out[base + r] = static_cast<float>(s);
    }
  }
}

ShRgb Rotation::apply(const ShRgb& in) const {
  PRT_CHECK_LE(in.bands, bands_);
  PRT_CHECK_EQ(in.size(), numCoeffs(in.bands));
  ShRgb out(in.bands);
  for (int l = 0; l < in.bands; ++l) {
    const int size = 2 * l + 1;
    const int base = l * l;
    const std::vector<double>& b = blocks_[l];
    for (int r = 0; r < size; ++r) {
      glm::dvec3 s(0.0);
      for (int c = 0; c < size; ++c) s += b[r * size + c] * glm::dvec3(in.c[base + c]);
      out.c[base + r] = glm::vec3(s);
    }
  }
  return out;
}

double Rotation::element(int l, int row, int col) const {
  PRT_CHECK(l >= 0 && l < bands_);
  PRT_CHECK(std::abs(row) <= l && std::abs(col) <= l);
  return Block(l, blocks_[l])(row, col);
}

glm::dmat3 rotationY(double degrees) { return rotationAxis(glm::dvec3(0.0, 1.0, 0.0), degrees); }

glm::dmat3 rotationAxis(const glm::dvec3& axis, double degrees) {
  const double len = glm::length(axis);
  PRT_CHECK_GT(len, 0.0);
  const glm::dvec3 k = axis / len;
  const double a = degrees * kPi / 180.0;
  const double c = std::cos(a), s = std::sin(a), t = 1.0 - c;
  // Rodrigues: R = c I + s [k]× + (1 - c) k kᵀ, right-handed. Written by columns (glm).
  const glm::dvec3 col0(c + t * k.x * k.x, t * k.x * k.y + s * k.z, t * k.x * k.z - s * k.y);
  const glm::dvec3 col1(t * k.x * k.y - s * k.z, c + t * k.y * k.y, t * k.y * k.z + s * k.x);
  const glm::dvec3 col2(t * k.x * k.z + s * k.y, t * k.y * k.z - s * k.x, c + t * k.z * k.z);
  return glm::dmat3(col0, col1, col2);
}

}  // namespace prt::sh
