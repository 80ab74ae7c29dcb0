// Distant lighting projected to SH: environment maps, sun disks, coloured sky disks.
//
// Orientation of equirectangular maps is Blender's (a map lights a glTF scene exactly as
// Cycles does with the same file as world texture, after Blender's glTF import). In glTF axes:
//   d = (x, y, z)  <->  u = 0.5 + atan2(z, x) / (2π),  v = acos(y) / π
// u runs left to right, v top to bottom; the image centre looks along +X.
#pragma once

#include <string>

#include <glm/glm.hpp>

#include "prt/image.h"
#include "prt/sh.h"

namespace prt {

/// Unit direction of texture coordinates (u, v) of an equirectangular map.
glm::dvec3 equirectDirection(double u, double v);
/// Texture coordinates of unit direction d: inverse of equirectDirection.
glm::dvec2 equirectUv(const glm::dvec3& d);

/// The map's radiance towards unit direction d, bilinear between pixel centres (pixel (x, y) at
/// u = (x + ½)/W, v = (y + ½)/H), wrapping around in u and clamped to the first and last row
/// in v: what a GL_LINEAR texture with GL_REPEAT in s and GL_CLAMP_TO_EDGE in t returns.
glm::dvec3 sampleEquirect(const ImageRgb& equirect, const glm::dvec3& d);

/// Exact solid angle of a pixel in row `row` of a width × height equirectangular map:
/// (2π/W)·(cos θ₀ - cos θ₁), θ₀ = π·row/H and θ₁ = π·(row+1)/H its row edges. The weights of
/// all pixels sum to 4π.
double equirectPixelSolidAngle(int row, int width, int height);

/// Projects an equirectangular radiance map onto n bands, each pixel weighted by its exact
/// solid angle (equirectPixelSolidAngle).
sh::ShRgb projectEnvironment(const ImageRgb& equirect, int bands);

/// SH of a uniform disk (spherical cap) of angular radius `radius` (radians) around unit
/// direction `toLight`, with uniform radiance `radiance`. radius = 0 is not allowed here.
sh::ShRgb projectDiskRadiance(int bands, const glm::dvec3& toLight, double radius, const glm::dvec3& radiance);

/// Below this angular radius (radians) a sun is a delta direction (projectSun, Note 3 there).
constexpr double kPointSunRadians = 1e-6;

/// SH of a sun: a disk of angular radius `radius` (radians, 0 = a delta direction) whose
/// irradiance on a surface facing it is `irradiance` (as Blender's sun "strength", W/m²).
/// Radiance inside the disk is irradiance / (π sin² radius).
sh::ShRgb projectSun(int bands, const glm::dvec3& toLight, double radius, const glm::dvec3& irradiance);

/// A uniform environment of the given radiance: only coefficient 0, = 2√π · radiance.
sh::ShRgb projectUniform(int bands, const glm::dvec3& radiance);

/// Suns and disks at most this angular radius (degrees) are direct lights (docs/lights.md,
/// "Direct lights"): their unoccluded light is computed exactly, with its shadow, and only
/// their bounced light goes through SH. Larger disks stay in the SH light.
constexpr double kMaxDirectRadiusDegrees = 20.0;

/// A small bright distant source lit exactly (docs/lights.md, "Direct lights"): a cap of
/// uniform radiance around `direction`.
struct DirectLight {
  glm::dvec3 direction{0.0, 1.0, 0.0};  // unit, towards the light
  double radius = 0.0;                  // angular radius (radians), below kPointSunRadians a delta
  glm::dvec3 irradiance{0.0};           // RGB irradiance on a surface facing it, unoccluded
  /// Radiance inside the cap, E / (π sin² r); 0 for a delta.
  glm::dvec3 radiance() const;
  /// Its SH on `bands` bands (projectSun).
  sh::ShRgb project(int bands) const;
};

/// Share of a direct light's irradiance that a surface with unit normal n receives when
/// nothing occludes it: ∫_cap max(n·ω, 0) dω / (π sin² r), exact (the cap clipped by the
/// surface's horizon, Note 4 in light.cpp); max(n·d, 0) for a delta. In [0, 1].
double directCosineFactor(const DirectLight& light, const glm::dvec3& n);

}  // namespace prt
