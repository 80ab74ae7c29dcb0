// The glTF metallic-roughness BRDF and GGX sampling (prt/brdf.h states the conventions and the
// references [n]).
#include "prt/brdf.h"

#include <algorithm>
#include <cmath>

#include "prt/math.h"

namespace prt::brdf {

double ggxD(double nDotH, double alpha) {
  if (nDotH <= 0.0) return 0.0;
  const double a2 = alpha * alpha;
  const double d = nDotH * nDotH * (a2 - 1.0) + 1.0;
  return a2 / (kPi * d * d);
}

double smithVisibility(double nDotL, double nDotV, double alpha) {
  if (nDotL <= 0.0 || nDotV <= 0.0) return 0.0;
  const double a2 = alpha * alpha;
  const double gv = nDotL * std::sqrt(nDotV * nDotV * (1.0 - a2) + a2);
  const double gl = nDotV * std::sqrt(nDotL * nDotL * (1.0 - a2) + a2);
  return 0.5 / (gv + gl);
}

double smithLambda(double cosTheta, double alpha) {
  const double c2 = cosTheta * cosTheta;
  const double tan2 = std::max(1.0 - c2, 0.0) / c2;
  return 0.5 * (-1.0 + std::sqrt(1.0 + alpha * alpha * tan2));
}

double schlick(double f0, double vDotH, double f90) {
  const double m = 1.0 - std::min(std::fabs(vDotH), 1.0);
  const double m2 = m * m;
  return f0 + (f90 - f0) * (m2 * m2 * m);
}

glm::dvec3 schlick(const glm::dvec3& f0, double vDotH, double f90) {
  return {schlick(f0.x, vDotH, f90), schlick(f0.y, vDotH, f90), schlick(f0.z, vDotH, f90)};
}

double dielectricF0(double ior) {
  const double r = (ior - 1.0) / (ior + 1.0);
  return r * r;
}

double schlickCosineAverage(double f0, double f90) { return f0 + (f90 - f0) / 21.0; }

glm::dvec3 MetallicRoughness::dielectricF0Color() const {
  return glm::min(dielectricF0(ior) * specularColor, glm::dvec3(1.0));
}

Lobes evaluate(const MetallicRoughness& m, const glm::dvec3& n, const glm::dvec3& l, const glm::dvec3& v) {
  const double nl = glm::dot(n, l), nv = glm::dot(n, v);
  if (nl <= 0.0 || nv <= 0.0) return {};
  const glm::dvec3 h = glm::normalize(l + v);
  const double vh = glm::dot(v, h), nh = glm::dot(n, h);
  const double r = std::max(m.roughness, kMinRoughness), alpha = r * r;
  const double specularBrdf = smithVisibility(nl, nv, alpha) * ggxD(nh, alpha);  // specular_brdf(α) = V·D [1]
  const glm::dvec3 fd = schlick(m.dielectricF0Color(), vh);                      // [2]
  const double fdMax = std::max({fd.x, fd.y, fd.z});
  const glm::dvec3 fm = schlick(m.baseColor, vh);  // conductor_fresnel(baseColor, ·) [1]
  Lobes out;
  out.diffuse = (1.0 - m.metallic) * (1.0 - m.specular * fdMax) * m.baseColor / kPi;
  out.specular = ((1.0 - m.metallic) * m.specular * fd + m.metallic * fm) * specularBrdf;
  return out;
}

double dielectricDiffuseWeight(double ior, double specular, const glm::dvec3& specularColor) {
  const glm::dvec3 f0 = glm::min(dielectricF0(ior) * specularColor, glm::dvec3(1.0));
  // F is increasing in F0 channel by channel, so max(F) is F of the largest F0 at every angle.
  const double f0Max = std::max({f0.x, f0.y, f0.z});
  return 1.0 - specular * (f0Max + (1.0 - f0Max) * kHalfVectorFresnelMean);
}

glm::dvec3 sampleGgxHalfVector(const glm::dvec2& u, double alpha) {
  // The cdf of cosθ under D(h)(n·h): P(cos²θ ≥ c) solved for c [3].
  const double a2 = alpha * alpha;
  const double cos2 = (1.0 - u.x) / (1.0 + (a2 - 1.0) * u.x);
  const double cosTheta = std::sqrt(std::clamp(cos2, 0.0, 1.0));
  const double sinTheta = std::sqrt(std::max(1.0 - cos2, 0.0));
  const double phi = 2.0 * kPi * u.y;
  return {sinTheta * std::cos(phi), sinTheta * std::sin(phi), cosTheta};
}

double pdfGgxHalfVector(const glm::dvec3& h, double alpha) { return ggxD(h.z, alpha) * std::max(h.z, 0.0); }

glm::dvec2 invertGgxHalfVector(const glm::dvec3& h, double alpha) {
  // cos² = (1 − u)/(1 + (α² − 1)u)  ⇔  u = (1 − cos²)/(1 + (α² − 1)cos²).
  const double a2 = alpha * alpha, cos2 = h.z * h.z;
  const double u0 = (1.0 - cos2) / (1.0 + (a2 - 1.0) * cos2);
  double phi = std::atan2(h.y, h.x);
  if (phi < 0.0) phi += 2.0 * kPi;
  return {std::clamp(u0, 0.0, 1.0), phi / (2.0 * kPi)};
}

glm::dvec3 sampleGgxReflection(const glm::dvec2& u, const glm::dvec3& v, double alpha) {
  const glm::dvec3 h = sampleGgxHalfVector(u, alpha);
  return 2.0 * glm::dot(v, h) * h - v;
}

double pdfGgxReflection(const glm::dvec3& l, const glm::dvec3& v, double alpha) {
  const glm::dvec3 sum = l + v;
  const double len = glm::length(sum);
  if (len <= 0.0) return 0.0;
  const glm::dvec3 h = sum / len;
  const double vh = std::fabs(glm::dot(v, h));
  // The Jacobian of l = reflect(v, h) is dω_h/dω_l = 1/(4|v·h|) [3].
  return vh > 0.0 ? pdfGgxHalfVector(h, alpha) / (4.0 * vh) : 0.0;
}

}  // namespace prt::brdf
