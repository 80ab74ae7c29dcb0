// Real spherical harmonics (SH): the one vocabulary of prt.
//
// Conventions (also in docs/conventions.md; every part of prt means exactly this):
// - "bands" n means degrees l = 0 .. n-1 and n² coefficients; 1 <= n <= kMaxBands (8).
// - Coefficient index i = l(l+1) + m, -l <= m <= l.
// - Real orthonormal basis: ∫ y_i y_j dω = δ_ij over the unit sphere.
// - No Condon-Shortley phase. In Cartesian form, with d = (x, y, z) a unit direction in the
//   glTF frame (+Y up, right-handed) used as is:
//     y_0  = 0.282095
//     y_1  = 0.488603 y      y_2 = 0.488603 z      y_3 = 0.488603 x
//     y_4  = 1.092548 xy     y_5 = 1.092548 yz     y_6 = 0.315392 (3z² - 1)
//     y_7  = 1.092548 xz     y_8 = 0.546274 (x² - y²)
//   i.e. the polar axis of the basis is +Z; m > 0 goes with cos(mφ), m < 0 with sin(|m|φ),
//   φ = atan2(y, x). This is the form of Ramamoorthi & Hanrahan [2] and of three.js
//   (SphericalHarmonics3), so coefficients can be exchanged with them directly.
// - A direction ω always points *towards* where light comes from.
// - Lighting L(ω) = Σ l_i y_i(ω) is radiance (W·sr⁻¹·m⁻², or any consistent unit).
//
// References
// [1] P.-P. Sloan, J. Kautz, J. Snyder. Precomputed Radiance Transfer for Real-Time Rendering
//     in Dynamic, Low-Frequency Lighting Environments. SIGGRAPH 2002.
// [2] R. Ramamoorthi, P. Hanrahan. An Efficient Representation for Irradiance Environment
//     Maps. SIGGRAPH 2001. (Clamped-cosine factors Â_l.)
// [3] J. Ivanic, K. Ruedenberg. Rotation Matrices for Real Spherical Harmonics. Direct
//     Determination by Recursion. J. Phys. Chem. 100(15), 1996, and the errata in
//     J. Phys. Chem. A 102(45), 1998. (Rotation of every band.)
// [4] P.-P. Sloan. Stupid Spherical Harmonics (SH) Tricks. GDC 2008. (Windowing.)
// [5] P.-P. Sloan. Deringing Spherical Harmonics. SIGGRAPH Asia 2017 Technical Briefs.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace prt::sh {

constexpr int kMaxBands = 8;

/// Number of coefficients for n bands: n².
constexpr int numCoeffs(int bands) { return bands * bands; }
/// Index of (l, m): l(l+1) + m.
constexpr int index(int l, int m) { return l * (l + 1) + m; }
/// Band (degree) l of coefficient index i.
int bandOf(int i);

/// Evaluates the bands² basis functions at unit direction d into out[0 .. bands²).
/// Precondition: 1 <= bands <= kMaxBands, |d| = 1.
void evaluate(int bands, const glm::vec3& d, float* out);
/// Same in double precision (tests, projections).
void evaluate(int bands, const glm::dvec3& d, double* out);
/// evaluate() at eight unit directions (x[k], y[k], z[k]), k < 8: out[8·i + k] is coefficient i
/// of direction k, with the same bits as evaluate() of that direction. At 3 bands with AVX2 the
/// eight lanes at once (evaluate's operations written out); otherwise one direction at a time.
void evaluate8(int bands, const float* x, const float* y, const float* z, float* out);
/// Convenience form returning a vector.
std::vector<float> evaluate(int bands, const glm::vec3& d);

/// Clamped-cosine band factor Â_l = 2π ∫₀¹ P_l(t) t dt: π, 2π/3, π/4, 0 for odd l > 1, ...
/// With E(N) = Σ Â_l(i) c_i y_i(N), SH radiance c gives irradiance at normal N [2].
double clampedCosineFactor(int l);

/// RGB coefficients: c[i] is the (r, g, b) of coefficient i. The type of lighting (light SH),
/// of incident radiance at a probe, and of one vertex's transfer vector.
struct ShRgb {
  int bands = 0;
  std::vector<glm::vec3> c;

  ShRgb() = default;
  explicit ShRgb(int n) : bands(n), c(static_cast<size_t>(n) * n, glm::vec3(0.0f)) {}
  int size() const { return static_cast<int>(c.size()); }
  ShRgb& operator+=(const ShRgb& o);
  ShRgb& operator*=(const glm::vec3& s);
  ShRgb& operator*=(float s);
};

/// The same coefficients truncated or zero-padded to `bands` bands.
ShRgb resize(const ShRgb& in, int bands);

/// Σ_i t_i l_i per channel (transfer · light).
glm::vec3 dot(const ShRgb& t, const ShRgb& l);
/// Same for raw arrays of n coefficients.
glm::vec3 dot(const glm::vec3* t, const glm::vec3* l, int n);

/// Reconstructs Σ c_i y_i(d).
glm::vec3 reconstruct(const ShRgb& c, const glm::vec3& d);

/// Irradiance at normal N of SH radiance c: Σ Â_l(i) c_i y_i(N).
glm::vec3 irradiance(const ShRgb& c, const glm::vec3& n);

/// Multiplies band l of c by Â_l in place (radiance -> irradiance as a function of N).
void convolveClampedCosine(ShRgb& c);

/// Projects f(ω) onto n bands by numerical quadrature: Gauss-Legendre in cos θ with
/// `thetaSamples` nodes times 2·thetaSamples uniform φ. Exact (to rounding) for functions that
/// are band-limited below min(2·thetaSamples, ...) — a tool for tests and analytic lights.
ShRgb projectFunction(int bands, const std::function<glm::vec3(const glm::dvec3&)>& f, int thetaSamples = 64);

/// Exact rotation of SH coefficients by a 3×3 rotation R, for every band [3]. If g(ω) = f(R⁻¹ω)
/// (the function turned by R), then coeffs(g) = D(R) · coeffs(f). D is block diagonal.
class Rotation {
 public:
  /// Precondition: R is a rotation (orthonormal, det +1), 1 <= bands <= kMaxBands.
  Rotation(int bands, const glm::dmat3& R);
  int bands() const { return bands_; }
  /// out = D · in, for n = bands² scalar coefficients. in and out may not alias.
  void apply(const float* in, float* out) const;
  /// Rotates RGB coefficients (bands may be <= bands()).
  ShRgb apply(const ShRgb& in) const;
  /// Element (row, col) of the block of band l, row/col in -l..l.
  double element(int l, int row, int col) const;

 private:
  int bands_;
  std::vector<std::vector<double>> blocks_;  // per band, (2l+1)² row-major
};

/// Rotation about +Y by `degrees`, right-handed: at +90°, light that came from +X comes from -Z.
glm::dmat3 rotationY(double degrees);
/// Rotation about an arbitrary unit axis by `degrees`, right-handed.
glm::dmat3 rotationAxis(const glm::dvec3& axis, double degrees);

/// Windows against ringing [4]: a factor w_l <= 1 per band, applied to the *light* only.
enum class Window { None, Hann, Lanczos };
/// Parses "none", "hann", "lanczos"; throws prt::Error otherwise.
Window parseWindow(const std::string& name);
const char* windowName(Window w);
/// w_l for band l of n bands. Hann: (1 + cos(π l / n)) / 2; Lanczos: sinc(l / n).
double windowFactor(Window w, int l, int bands);
/// Multiplies band l of c by windowFactor(w, l, c.bands).
void applyWindow(ShRgb& c, Window w);

}  // namespace prt::sh
