// Lights inside the scene and their unoccluded irradiance (prt/local_light.h).
#include "prt/local_light.h"

#include <algorithm>
#include <cmath>

#include "prt/error.h"
#include "prt/light.h"
#include "prt/math.h"

namespace prt {

bool LocalLight::operator==(const LocalLight& o) const {
  return type == o.type && position == o.position && direction == o.direction && up == o.up &&
         intensity == o.intensity && radiance == o.radiance && range == o.range && innerCone == o.innerCone &&
         outerCone == o.outerCone && radius == o.radius && width == o.width && height == o.height &&
         corners == o.corners && emitter == o.emitter;
}

const char* localLightTypeName(LocalLight::Type type) {
  switch (type) {
    case LocalLight::Type::Point:
      return "point";
    case LocalLight::Type::Spot:
      return "spot";
    case LocalLight::Type::Sphere:
      return "sphere";
    case LocalLight::Type::Disk:
      return "disk";
    case LocalLight::Type::Rectangle:
      return "rectangle";
    case LocalLight::Type::Triangle:
      return "triangle";
    case LocalLight::Type::Emitter:
      return "emissive";
  }
  return "?";
}

namespace {

[[noreturn]] void fail(const LocalLight& l, const char* field, const std::string& problem) {
  throw Error(cat(l.label.empty() ? std::string("light") : l.label, ": ", field, ": ", problem));
}

void checkColor(const LocalLight& l, const glm::dvec3& c, const char* field) {
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(c[k])) fail(l, field, "not a finite number");
    if (c[k] < 0.0) fail(l, field, cat("must be >= 0 (got ", c[k], ")"));
  }
}

void checkUnit(const LocalLight& l, const glm::dvec3& d, const char* field) {
  const double len = glm::length(d);
  if (!std::isfinite(len) || std::abs(len - 1.0) > 1e-6) fail(l, field, "not a unit direction");
}

void checkSize(const LocalLight& l, double x, const char* field) {
  if (!std::isfinite(x)) fail(l, field, "not a finite number");
  if (!(x > 0.0)) fail(l, field, cat("an area light needs a size > 0 (got ", x, ")"));
}

}  // namespace

void validate(const LocalLight& l) {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(l.position[k])) fail(l, "position", "not a finite number");
  if (l.punctual()) {
    checkColor(l, l.intensity, "intensity");
    if (!std::isfinite(l.range) || l.range < 0.0)
      fail(l, "range", cat("must be >= 0 (0: infinite; got ", l.range, ")"));
  } else {
    checkColor(l, l.radiance, "radiance");
  }
  if (l.type == LocalLight::Type::Emitter) {
    if (!l.emitter || l.emitter->triangles.empty()) fail(l, "triangles", "an emissive surface needs triangles");
    for (const LocalLight& t : l.emitter->triangles) validate(t);
    return;
  }
  if (l.type != LocalLight::Type::Point && l.type != LocalLight::Type::Sphere) checkUnit(l, l.direction, "direction");
  if (l.type == LocalLight::Type::Triangle) checkSize(l, localLightArea(l), "area");
  if (l.type == LocalLight::Type::Spot) {
    if (!std::isfinite(l.innerCone) || l.innerCone < 0.0)
      fail(l, "innerConeAngle", cat("must be >= 0 (got ", l.innerCone, ")"));
    if (!std::isfinite(l.outerCone) || l.outerCone > kPi / 2.0 + 1e-9)
      fail(l, "outerConeAngle", cat("must be at most π/2 (got ", l.outerCone, ")"));
    if (!(l.innerCone < l.outerCone))
      fail(l, "innerConeAngle",
           cat("the inner cone (", l.innerCone, ") must be inside the outer cone (", l.outerCone, ")"));
  }
  if (l.type == LocalLight::Type::Sphere || l.type == LocalLight::Type::Disk) checkSize(l, l.radius, "radius");
  if (l.type == LocalLight::Type::Rectangle) {
    checkUnit(l, l.up, "up");
    checkSize(l, l.width, "width");
    checkSize(l, l.height, "height");
  }
}

double rangeWindow(double distance, double range) {
  if (range <= 0.0) return 1.0;
  const double q = distance / range, q2 = q * q;
  return std::clamp(1.0 - q2 * q2, 0.0, 1.0);
}

double spotFalloff(const LocalLight& l, const glm::dvec3& fromLight) {
  if (l.type != LocalLight::Type::Spot) return 1.0;
  const double scale = 1.0 / std::max(0.001, std::cos(l.innerCone) - std::cos(l.outerCone));
  const double offset = -std::cos(l.outerCone) * scale;
  const double a = std::clamp(glm::dot(l.direction, fromLight) * scale + offset, 0.0, 1.0);
  return a * a;
}

double localLightArea(const LocalLight& l) {
  switch (l.type) {
    case LocalLight::Type::Sphere:
      return 4.0 * kPi * l.radius * l.radius;
    case LocalLight::Type::Disk:
      return kPi * l.radius * l.radius;
    case LocalLight::Type::Rectangle:
      return l.width * l.height;
    case LocalLight::Type::Triangle:
      return 0.5 * glm::length(glm::cross(l.corners[1] - l.corners[0], l.corners[2] - l.corners[0]));
    case LocalLight::Type::Emitter:
      return l.emitter ? l.emitter->area : 0.0;
    default:
      return 0.0;
  }
}

glm::dvec3 localLightFromPower(const LocalLight& l, const glm::dvec3& power) {
  // A Lambertian emitter of radiance L sends π L per unit area into its hemisphere: Φ = π L A
  // (a sphere's A is 4πR²). A point light of intensity I sends 4π I.
  if (l.punctual()) return power / (4.0 * kPi);
  return power / (kPi * localLightArea(l));
}

glm::dvec3 orthogonalTo(const glm::dvec3& d, const glm::dvec3& up) {
  glm::dvec3 u = up - glm::dot(up, d) * d;
  if (glm::length(u) < 1e-9) u = std::abs(d.y) < 0.9 ? glm::dvec3(0, 1, 0) - d.y * d : glm::dvec3(1, 0, 0) - d.x * d;
  return glm::normalize(u);
}

std::vector<glm::dvec3> localLightPolygon(const LocalLight& l) {
  if (l.type == LocalLight::Type::Triangle) return {l.corners[0], l.corners[1], l.corners[2]};
  const glm::dvec3 b = orthogonalTo(l.direction, l.up), t = glm::cross(b, l.direction);
  if (l.type == LocalLight::Type::Rectangle) {
    const glm::dvec3 hw = 0.5 * l.width * t, hh = 0.5 * l.height * b;
    return {l.position - hw - hh, l.position + hw - hh, l.position + hw + hh, l.position - hw + hh};
  }
  // The regular N-gon of the disk's area: (N/2) R'² sin(2π/N) = π R².
  const int n = kDiskPolygonSides;
  const double step = 2.0 * kPi / n, r = l.radius * std::sqrt(step / std::sin(step));
  std::vector<glm::dvec3> p(n);
  for (int k = 0; k < n; ++k) p[k] = l.position + r * (std::cos(k * step) * t + std::sin(k * step) * b);
  return p;
}

double polygonCosineIntegral(const std::vector<glm::dvec3>& polygon, const glm::dvec3& x, const glm::dvec3& n) {
  // Clip against the horizon plane n·(p − x) >= 0 (Sutherland–Hodgman), then Lambert's formula
  // over the clipped polygon's edges: ∫ cos = ½ |Σ_i Θ_i n·Γ_i|, Θ_i the angle the edge
  // subtends, Γ_i the unit normal of the plane through x and the edge. The absolute value
  // makes the winding irrelevant (the clipped polygon lies in one half-space).
  std::vector<glm::dvec3> c;
  c.reserve(polygon.size() + 2);
  for (size_t i = 0; i < polygon.size(); ++i) {
    const glm::dvec3 a = polygon[i] - x, b = polygon[(i + 1) % polygon.size()] - x;
    const double da = glm::dot(n, a), db = glm::dot(n, b);
    if (da >= 0.0) c.push_back(a);
    if ((da >= 0.0) != (db >= 0.0)) c.push_back(a + (b - a) * (da / (da - db)));
  }
  if (c.size() < 3) return 0.0;
  double sum = 0.0;
  for (size_t i = 0; i < c.size(); ++i) {
    const glm::dvec3 a = c[i], b = c[(i + 1) % c.size()];
    const glm::dvec3 g = glm::cross(a, b);
    const double len = glm::length(g);
    if (len <= 0.0) continue;
    const double theta = std::atan2(len, glm::dot(a, b));
    sum += theta * glm::dot(n, g) / len;
  }
  return 0.5 * std::abs(sum);
}

glm::dvec3 localIrradiance(const LocalLight& l, const glm::dvec3& x, const glm::dvec3& n) {
  const glm::dvec3 toLight = l.position - x;
  const double d = glm::length(toLight);
  switch (l.type) {
    case LocalLight::Type::Point:
    case LocalLight::Type::Spot: {
      if (!(d > 0.0) || (l.range > 0.0 && d >= l.range)) return glm::dvec3(0.0);
      const glm::dvec3 w = toLight / d;
      const double cosTheta = glm::dot(n, w);
      if (cosTheta <= 0.0) return glm::dvec3(0.0);
      return l.intensity * (cosTheta / (d * d) * rangeWindow(d, l.range) * spotFalloff(l, -w));
    }
    case LocalLight::Type::Sphere: {
      // From outside, a sphere is a cap of angular radius asin(R/d): π L sin² α times the
      // horizon-clipped cosine factor of that cap (prt/light.h).
      if (!(d > l.radius)) return glm::dvec3(0.0);
      const double sinA = l.radius / d;
      DirectLight cap;
      cap.direction = toLight / d;
      cap.radius = std::asin(sinA);
      return l.radiance * (kPi * sinA * sinA * directCosineFactor(cap, n));
    }
    case LocalLight::Type::Emitter: {
      glm::dvec3 sum(0.0);
      for (const LocalLight& t : l.emitter->triangles) sum += localIrradiance(t, x, n);
      return sum;
    }
    case LocalLight::Type::Disk:
    case LocalLight::Type::Rectangle:
    case LocalLight::Type::Triangle:
      if (glm::dot(l.direction, x - l.position) <= 0.0) return glm::dvec3(0.0);  // behind its emitting side
      return l.radiance * polygonCosineIntegral(localLightPolygon(l), x, n);
  }
  return glm::dvec3(0.0);
}

LocalLight makeEmitter(const std::string& label, std::vector<LocalLight> triangles) {
  auto t = std::make_shared<LocalLight::Triangles>();
  double total = 0.0;
  glm::dvec3 centre(0.0);
  for (const LocalLight& tri : triangles) {
    const double a = localLightArea(tri);
    const glm::dvec3& L = tri.radiance;
    total += luminance(glm::dvec3(L)) * a;
    t->cdf.push_back(total);
    t->area += a;
    t->power += kPi * a * L;
    centre += a * tri.position;
  }
  for (double& c : t->cdf) c = total > 0.0 ? c / total : 1.0;
  if (!t->cdf.empty()) t->cdf.back() = 1.0;
  LocalLight l;
  l.type = LocalLight::Type::Emitter;
  l.label = label;
  l.position = t->area > 0.0 ? centre / t->area : centre;
  t->triangles = std::move(triangles);
  l.emitter = std::move(t);
  return l;
}

}  // namespace prt
