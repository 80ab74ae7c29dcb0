// The sun inside an environment map: finding the compact bright source that carries much of a
// map's power, modelling it as a uniform cap, and in-painting the map where it was.
//
// A sun holds a large share of a real map's power in a few pixels; no SH band count carries it
// (docs/lights.md, "Suns in environment maps: extractSun"). extractSun splits the map into a
// direct light (a cap: direction, angular radius, irradiance, as projectSun takes) and a
// residual map that is smooth where the sun was, such that
//   residual power + sun power = map power
// per channel, to float rounding: the sun is defined as the excess of the map over the
// in-painted background.
//
// Directions are in glTF axes for the map as stored (unrotated), in the orientation of
// prt/light.h.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include <glm/glm.hpp>

#include "prt/image.h"
#include "prt/math.h"

namespace prt {

/// How extractSun decides what is a sun. The defaults and why: docs/lights.md.
struct SunExtractOptions {
  /// Largest angular radius (radians) of a region treated as a sun, measured from the
  /// brightest pixel: 20°, the direct-light limit. A bright region reaching further is not
  /// compact and is left to the SH.
  double maxRadius = 20.0 * kPi / 180.0;
  /// The region is grown from the brightest pixel over the pixels whose luminance is at least
  /// this fraction of the peak's (the first threshold tried). 1/100: a real sun is 10³–10⁵
  /// times its sky, so this takes its disk and the bright core of its glare; the faint tail
  /// left behind is smooth and carries a few tenths of a percent.
  double peakFraction = 0.01;
  /// A source must stand this many times above the sky where its region ends: thresholds are
  /// doubled from peakFraction·peak while the region is not compact, up to peak / minContrast,
  /// and the median luminance of the ring just outside the region must be at most
  /// peak / minContrast. 16: smooth skies (gradients, overcast, the glow of a sunset) change by
  /// less than that within 20°.
  double minContrast = 16.0;
  /// Smallest share of the map's power (luminance) a sun must carry. 2%: below it the
  /// source's band-limited ringing costs less than the SH error of the rest of the map.
  double minPowerShare = 0.02;
  /// Pixels added around the thresholded region before in-painting (8-neighbour dilation,
  /// wrapping in u and across the poles): the filtered edge of a source in a resampled map
  /// spreads over about a pixel either side.
  int marginPixels = 2;
};

/// A sun found in a map, modelled as a uniform cap of radiance L and angular radius r.
struct ExtractedSun {
  glm::dvec3 direction{0.0, 1.0, 0.0};  ///< unit, towards the sun (glTF axes, the map as stored)
  double radius = 0.0;                  ///< angular radius (radians) of the cap; 0: a delta
  glm::dvec3 irradiance{0.0};           ///< RGB on a surface facing it: π L sin² r (what projectSun takes)
  glm::dvec3 power{0.0};                ///< RGB ∫ L dω of the extracted excess = L · 2π(1 − cos r)
  double powerShare = 0.0;              ///< luminance of `power` over the luminance of the map's power
  size_t pixels = 0;                    ///< pixels in the in-painted region
};

/// What extractSun returns: the sun, if any, and the map without it.
struct SunExtraction {
  std::optional<ExtractedSun> sun;  ///< empty: no compact bright source (`reason` says why)
  ImageRgb residual;                ///< the map, in-painted where the sun was (the map if no sun)
  glm::dvec3 mapPower{0.0};         ///< Σ L ΔΩ over the map's pixels (exact pixel solid angles)
  glm::dvec3 residualPower{0.0};    ///< the same sum over the residual
  std::string reason;               ///< why nothing was extracted, or what was
};

/// Finds the compact bright source around the brightest pixel of an equirectangular radiance
/// map (docs/lights.md has the method and the criterion), deterministic. Throws prt::Error on
/// an empty map, a pixel count that does not match its size, or non-finite pixels.
SunExtraction extractSun(const ImageRgb& equirect, const SunExtractOptions& options = {});

}  // namespace prt
