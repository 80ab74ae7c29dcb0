// Lights inside the scene: point and spot lights (KHR_lights_punctual) and area lights (sphere,
// disk, rectangle), in world space, with their unoccluded irradiance in closed form
// (docs/lights.md, "Lights inside the scene").
//
// Units are those of the rest of prt: a uniform sky of radiance 1 gives irradiance π. A point or
// spot light of intensity I (KHR_lights_punctual's candela, colour × intensity) gives
// E = I · cos θ / r² · window(r) · falloff at distance r; an area light is a radiance L on its
// surface (the units of an environment map), emitted on one side (disk, rectangle: the side
// `direction` points to) or outwards (sphere).
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "prt/math.h"

namespace prt {

struct LocalLight {
  enum class Type { Point, Spot, Sphere, Disk, Rectangle, Triangle, Emitter };
  Type type = Type::Point;
  std::string label;  // where it came from, for messages and summaries: "scene.glb: light 0 'Lamp'"
  glm::dvec3 position{0.0};
  /// Unit. Spot: the axis of its cone (the way the light travels, the node's −Z). Disk,
  /// rectangle, triangle: the normal of the emitting side.
  glm::dvec3 direction{0.0, -1.0, 0.0};
  /// Rectangle: unit, along its `height` side (made orthogonal to `direction`).
  glm::dvec3 up{0.0, 0.0, 1.0};
  glm::dvec3 intensity{0.0};                      // point, spot: candela, RGB
  glm::dvec3 radiance{0.0};                       // sphere, disk, rectangle: radiance, RGB
  double range = 0.0;                             // point, spot: metres, 0 = infinite
  double innerCone = 0.0, outerCone = kPi / 4.0;  // spot: radians, 0 <= inner < outer <= π/2
  double radius = 0.0;                            // sphere, disk: metres
  double width = 0.0, height = 0.0;               // rectangle: metres (width across `up`)
  /// Triangle (an emissive surface's): its corners; `position` is their centroid.
  std::array<glm::dvec3, 3> corners{};
  /// Emitter (an emissive surface): its triangles, each a Triangle light with its own radiance,
  /// shared (the same surface in every frame is the same pointer); see makeEmitter.
  struct Triangles {
    std::vector<LocalLight> triangles;
    std::vector<double> cdf;  // by luminance × area, cdf.back() == 1
    double area = 0.0;
    glm::dvec3 power{0.0};  // π L A summed: the watts it sends out
  };
  std::shared_ptr<const Triangles> emitter;

  bool punctual() const { return type == Type::Point || type == Type::Spot; }
  bool operator==(const LocalLight& o) const;
};

/// "point", "spot", "sphere", "disk", "rectangle", "triangle", "emissive".
const char* localLightTypeName(LocalLight::Type type);

/// Throws prt::Error "LABEL: FIELD: problem" unless every value is finite and in range: colours
/// >= 0, range >= 0, 0 <= inner cone < outer cone <= π/2, unit directions, sizes > 0.
void validate(const LocalLight& light);

/// KHR_lights_punctual's recommended range window: max(min(1 − (d/range)⁴, 1), 0); 1 for range 0.
double rangeWindow(double distance, double range);

/// The spot's angular falloff as KHR_lights_punctual's reference code: s = saturate(cd · scale +
/// offset)², scale = 1 / max(0.001, cos inner − cos outer), offset = −cos outer · scale, cd the
/// cosine between the spot's axis and the unit direction `fromLight` (light to point). 1 for a
/// point light.
double spotFalloff(const LocalLight& light, const glm::dvec3& fromLight);

/// Surface area of an area light (sphere 4πR², disk πR², rectangle w·h, a triangle's); 0 for a
/// point or spot.
double localLightArea(const LocalLight& light);

/// The radiance of an area light of `power` watts (RGB): Φ / (π A) for a one-sided disk or
/// rectangle, Φ / (4π² R²) for a sphere; and the intensity of a point or spot light of `power`,
/// Φ / (4π) (as Blender's point light; the spot's cone masks, it does not concentrate).
glm::dvec3 localLightFromPower(const LocalLight& light, const glm::dvec3& power);

/// Unoccluded irradiance at point x with unit normal n (RGB): exact for point, spot, sphere,
/// rectangle and triangle; the disk is its area-matched kDiskPolygonSides-gon (docs/lights.md gives the
/// error). 0 behind a disk, rectangle or triangle and inside a sphere.
glm::dvec3 localIrradiance(const LocalLight& light, const glm::dvec3& x, const glm::dvec3& n);
constexpr int kDiskPolygonSides = 128;

/// ∫ max(n·ω, 0) dω over the solid angle a planar convex polygon subtends from x, the polygon
/// clipped by x's horizon first (Lambert's formula, ½ Σ_i Θ_i n·Γ_i).
double polygonCosineIntegral(const std::vector<glm::dvec3>& polygon, const glm::dvec3& x, const glm::dvec3& n);

/// The corners of a rectangle (4) or triangle light (3), or of a disk's area-matched polygon, in
/// order.
std::vector<glm::dvec3> localLightPolygon(const LocalLight& light);

/// An emissive surface of `triangles` (Triangle lights of radiance > 0) as one light: its
/// closed form is their sum, its samples are spread over them by luminance × area.
LocalLight makeEmitter(const std::string& label, std::vector<LocalLight> triangles);

/// A unit vector orthogonal to unit `d`: `up` made orthogonal, or any when `up` is parallel.
glm::dvec3 orthogonalTo(const glm::dvec3& d, const glm::dvec3& up);

}  // namespace prt
