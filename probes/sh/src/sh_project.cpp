// Projection of functions onto SH by quadrature, and windows against ringing.
// Conventions: prt/sh.h.
#include <algorithm>
#include <cmath>
#include <vector>

#include "prt/error.h"
#include "prt/math.h"
#include "prt/sh.h"

namespace prt::sh {

namespace {

struct GaussLegendre {
  std::vector<double> x, w;
};

// Nodes and weights of n-point Gauss-Legendre quadrature on [-1, 1], exact for polynomials of
// degree <= 2n-1. The nodes are the roots of P_n, found by Newton iteration from the
// asymptotic guess cos(π (i + 3/4) / (n + 1/2)); P_n and P_{n-1} come from Bonnet's recurrence
// k P_k = (2k-1) t P_{k-1} - (k-1) P_{k-2}, and P_n'(t) = n (t P_n - P_{n-1}) / (t² - 1).
// The weight is w = 2 / ((1 - t²) P_n'(t)²). Roots are symmetric, so half are computed.
GaussLegendre gaussLegendre(int n) {
  GaussLegendre g;
  g.x.resize(static_cast<size_t>(n));
  g.w.resize(static_cast<size_t>(n));
  for (int i = 0; i < (n + 1) / 2; ++i) {
    double t = std::cos(kPi * (i + 0.75) / (n + 0.5));
    double dp = 1.0;
    for (int iter = 0; iter < 100; ++iter) {
      double p0 = 1.0, p1 = t;  // P_{k-1}, P_k
      for (int k = 2; k <= n; ++k) {
        double p2 = ((2.0 * k - 1.0) * t * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (t * p1 - p0) / (t * t - 1.0);
      double step = p1 / dp;
      t -= step;
      if (std::abs(step) < 1e-15) break;
    }
    double w = 2.0 / ((1.0 - t * t) * dp * dp);
    g.x[i] = -t;
    g.x[n - 1 - i] = t;
    g.w[i] = w;
    g.w[n - 1 - i] = w;
  }
  return g;
}

}  // namespace

ShRgb projectFunction(int bands, const std::function<glm::vec3(const glm::dvec3&)>& f, int thetaSamples) {
  PRT_CHECK(bands >= 1 && bands <= kMaxBands);
  PRT_CHECK_GE(thetaSamples, 1);
  // The basis' polar axis is +Z, so t = cos θ = z. In t the integrand y_i·f is a polynomial
  // (after the φ sum removes odd powers of sin θ), which Gauss-Legendre integrates exactly;
  // in φ it is a trigonometric polynomial, which the uniform rule integrates exactly up to
  // frequency 2·thetaSamples - 1.
  const GaussLegendre gl = gaussLegendre(thetaSamples);
  const int nPhi = 2 * thetaSamples;
  const double dPhi = 2.0 * kPi / nPhi;
  std::vector<double> cosPhi(static_cast<size_t>(nPhi)), sinPhi(static_cast<size_t>(nPhi));
  for (int j = 0; j < nPhi; ++j) {
    double phi = (j + 0.5) * dPhi;
    cosPhi[j] = std::cos(phi);
    sinPhi[j] = std::sin(phi);
  }

  const int n = numCoeffs(bands);
  std::vector<glm::dvec3> acc(static_cast<size_t>(n), glm::dvec3(0.0));
  double y[kMaxBands * kMaxBands];
  for (int i = 0; i < thetaSamples; ++i) {
    const double t = gl.x[i];
    const double s = std::sqrt(std::max(0.0, 1.0 - t * t));
    const double w = gl.w[i] * dPhi;
    for (int j = 0; j < nPhi; ++j) {
      const glm::dvec3 d(s * cosPhi[j], s * sinPhi[j], t);
      const glm::dvec3 v = glm::dvec3(f(d)) * w;
      evaluate(bands, d, y);
      for (int k = 0; k < n; ++k) acc[k] += v * y[k];
    }
  }

  ShRgb out(bands);
  for (int k = 0; k < n; ++k) out.c[k] = glm::vec3(acc[k]);
  return out;
}

Window parseWindow(const std::string& name) {
  if (name == "none") return Window::None;
  if (name == "hann") return Window::Hann;
  if (name == "lanczos") return Window::Lanczos;
  throw Error(cat("unknown window '", name, "' (expected none, hann or lanczos)"));
}

const char* windowName(Window w) {
  switch (w) {
    case Window::None:
      return "none";
    case Window::Hann:
      return "hann";
    case Window::Lanczos:
      return "lanczos";
  }
  return "none";
}

double windowFactor(Window w, int l, int bands) {
  PRT_CHECK_GE(bands, 1);
  PRT_CHECK(l >= 0 && l < bands);
  const double x = double(l) / double(bands);
  switch (w) {
    case Window::None:
      return 1.0;
    case Window::Hann:
      return 0.5 * (1.0 + std::cos(kPi * x));
    case Window::Lanczos:
      return l == 0 ? 1.0 : std::sin(kPi * x) / (kPi * x);
  }
  return 1.0;
}

void applyWindow(ShRgb& c, Window w) {
  for (int l = 0; l < c.bands; ++l) {
    const float f = static_cast<float>(windowFactor(w, l, c.bands));
    for (int m = -l; m <= l; ++m) c.c[index(l, m)] *= f;
  }
}

}  // namespace prt::sh
