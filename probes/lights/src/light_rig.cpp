// Light rigs: keyframed distant lights (prt/light_rig.h): tracks, validation, the map cache and
// the evaluation of a frame. The JSON reader is light_rig_json.cpp; the format is in docs/lights.md.
#include "prt/light_rig.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <map>
#include <mutex>
#include <optional>
#include <utility>

#include "light_rig_checks.h"
#include "prt/error.h"
#include "prt/image.h"
#include "prt/light.h"
#include "prt/math.h"

namespace prt {

using detail::checkFps;

namespace {

// Spherical interpolation of unit vectors a, b (not opposite) at t in [0, 1]. The angle comes
// from atan2(|a×b|, a·b), accurate at every angle; below 1e-9 rad the chord is the arc to
// rounding, so a normalised lerp is used there.
glm::dvec3 slerp(const glm::dvec3& a, const glm::dvec3& b, double t) {
  const double angle = std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
  if (angle < 1e-9) return glm::normalize((1.0 - t) * a + t * b);
  const double s = std::sin(angle);
  return glm::normalize(std::sin((1.0 - t) * angle) / s * a + std::sin(t * angle) / s * b);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Tracks

Track Track::constant(const glm::dvec3& value) {
  Track t;
  t.keys.push_back({0.0, value});
  return t;
}

Track Track::ramp(double f0, double v0, double f1, double v1) {
  if (f1 <= f0) return constant(v0);
  Track t;
  t.keys.push_back({f0, glm::dvec3(v0)});
  t.keys.push_back({f1, glm::dvec3(v1)});
  return t;
}

glm::dvec3 Track::at(double frame) const {
  PRT_CHECK(!keys.empty());
  // The first key after `frame`; the segment is [it - 1, it]. A frame equal to a key's frame
  // selects that key as the segment's start, so keys are reproduced exactly.
  auto it = std::upper_bound(keys.begin(), keys.end(), frame, [](double f, const Key& k) { return f < k.frame; });
  if (it == keys.begin()) return keys.front().value;  // before the first key: hold it
  if (it == keys.end()) return keys.back().value;     // after the last key: hold it
  const Key& k0 = *(it - 1);
  const Key& k1 = *it;
  if (interp == Interp::Step) return k0.value;
  const double t = (frame - k0.frame) / (k1.frame - k0.frame);
  if (direction) return slerp(k0.value, k1.value, t);
  // Rounding can put the line a last bit outside [k0, k1] (two keys at 89.99999999999999 could
  // give 90); clamped, an interpolated value stays in every convex range its keys are in.
  const glm::dvec3 v = (1.0 - t) * k0.value + t * k1.value;
  return glm::clamp(v, glm::min(k0.value, k1.value), glm::max(k0.value, k1.value));
}

glm::dvec3 azimuthElevationDirection(double azimuthDegrees, double elevationDegrees) {
  const double az = azimuthDegrees * kPi / 180.0, el = elevationDegrees * kPi / 180.0;
  return {std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az)};
}

glm::dvec3 RigLight::directionAt(double frame) const {
  if (useAzimuthElevation) return azimuthElevationDirection(azimuth.scalarAt(frame), elevation.scalarAt(frame));
  return direction.at(frame);
}

// ---------------------------------------------------------------------------------------------
// Validation. Every message is "SOURCE: PATH: problem", PATH being where the value was written
// (Track::origin): "lights[1].radius.keys[2].frame" in a file, "--sun-radius" on the command line.

namespace {

enum class Range { Any, NonNegative, Positive, OuterCone, Elevation, SunRadius, DiskRadius, DiskIrradianceRadius };

struct Checker {
  std::string prefix;  // "rig.json: " or ""

  [[noreturn]] void fail(const std::string& path, const std::string& problem) const {
    throw Error(cat(prefix, path, ": ", problem));
  }

  // Where key k of a track was written.
  static std::string keyPath(const Track& t, const std::string& origin, size_t k, const char* field) {
    return t.keyList ? cat(origin, "[", k, "].", field) : origin;
  }

  void frames(const Track& t, const std::string& origin) const {
    if (t.keys.empty()) fail(origin, "no keyframes");
    if (t.keys.size() > RigLimits::kMaxKeys)
      fail(origin, cat(t.keys.size(), " keys (at most ", RigLimits::kMaxKeys, ")"));
    for (size_t k = 0; k < t.keys.size(); ++k) {
      const double f = t.keys[k].frame;
      if (!std::isfinite(f)) fail(keyPath(t, origin, k, "frame"), "frame is not a finite number");
      if (std::abs(f) > RigLimits::kMaxFrame)
        fail(keyPath(t, origin, k, "frame"), cat("frame ", f, " is beyond ±", RigLimits::kMaxFrame));
      if (k > 0 && !(t.keys[k].frame > t.keys[k - 1].frame))
        fail(keyPath(t, origin, k, "frame"),
             cat("frames must increase (", t.keys[k].frame, " after ", t.keys[k - 1].frame, ")"));
    }
  }

  void values(const Track& t, const std::string& origin, Range range, int components) const {
    frames(t, origin);
    for (size_t k = 0; k < t.keys.size(); ++k) {
      const std::string where = keyPath(t, origin, k, "value");
      for (int c = 0; c < components; ++c) {
        const double x = t.keys[k].value[c];
        if (!std::isfinite(x)) fail(where, "not a finite number");
        if (std::abs(x) > RigLimits::kMaxValue) fail(where, cat(x, " is beyond ±", RigLimits::kMaxValue));
        switch (range) {
          case Range::Any:
            break;
          case Range::NonNegative:
            if (x < 0) fail(where, cat("must be >= 0 (got ", x, ")"));
            break;
          case Range::Positive:
            if (!(x > 0)) fail(where, cat("an area light needs a size > 0 (got ", x, ")"));
            break;
          case Range::OuterCone:
            if (!(x > 0 && x <= 90)) fail(where, cat("the outer cone must be in (0, 90] degrees (got ", x, ")"));
            break;
          case Range::Elevation:
            if (x < -90 || x > 90) fail(where, cat("elevation must be in [-90, 90] degrees (got ", x, ")"));
            break;
          case Range::SunRadius:
            if (!(x >= 0 && x < 90)) fail(where, cat("sun radius must be in [0, 90) degrees (got ", x, ")"));
            break;
          case Range::DiskRadius:
            if (!(x > 0 && x <= 180)) fail(where, cat("disk radius must be in (0, 180] degrees (got ", x, ")"));
            // Below 3e-322 degrees the radius is 0 in radians, which projectDiskRadiance refuses.
            if (!(glm::radians(x) > 0)) fail(where, cat("disk radius ", x, " degrees is 0 in radians"));
            break;
          case Range::DiskIrradianceRadius:
            if (!(x > 0 && x < 90))
              fail(where, cat("a disk given by irradiance needs a radius in (0, 90) degrees (got ", x, ")"));
            break;
        }
      }
    }
  }

  // Directions: non-zero, normalised here; neighbouring keys must not be opposite, where the
  // great circle between them (slerp) is undefined.
  void directions(Track& t, const std::string& origin) const {
    values(t, origin, Range::Any, 3);
    t.direction = true;
    for (size_t k = 0; k < t.keys.size(); ++k) {
      const double len = glm::length(t.keys[k].value);
      if (!(len > 1e-12)) fail(keyPath(t, origin, k, "value"), "direction is zero");
      t.keys[k].value /= len;
      if (k > 0 && t.interp == Track::Interp::Linear && glm::dot(t.keys[k].value, t.keys[k - 1].value) < -1.0 + 1e-12)
        fail(keyPath(t, origin, k, "value"),
             "opposite to the previous key: the path between them is undefined (add a key in between)");
    }
  }

  // Note: an environment's SH stays finite in float. A coefficient of a map projected with
  // pixel weights summing to 4π is at most 4π · max|y_lm| · M ≤ 4π · 1.1 · M for the brightest
  // channel M (|y_lm| ≤ √((2l+1)/4π) ≤ 1.1 for l ≤ 7); a rotation keeps each band's length, so
  // a rotated coefficient is at most √15 times that; times the intensity. With M and M ·
  // intensity ≤ kMaxMapRadiance (1e30) a light gives at most 5.4e31, and kMaxLights (1024) of
  // them 5.5e34, below float's 3.4e38. Analytic lights stay far below: values ≤ 1e12 and their
  // factors ≤ 4π (light.cpp).
  void mapRadiance(const RigLight& light, double brightest, const std::string& origin) const {
    const double limit = RigLimits::kMaxMapRadiance;
    const std::string file = light.label.empty() ? light.file : light.label + ".file";
    if (std::isnan(brightest)) fail(file, "a pixel is not a number (NaN)");
    if (brightest > limit) fail(file, cat("brightest pixel ", brightest, " is beyond ", limit));
    const Track& t = light.intensity;
    for (size_t k = 0; k < t.keys.size(); ++k) {
      const double x = std::max({t.keys[k].value.x, t.keys[k].value.y, t.keys[k].value.z});
      if (x * brightest > limit)
        fail(keyPath(t, origin, k, "value"),
             cat("intensity ", x, " times the map's brightest pixel ", brightest, " is beyond ", limit));
    }
  }
};

template <class Light>
std::string originOf(const Light& light, const Track& t, const char* field) {
  if (!t.origin.empty()) return t.origin;
  return light.label.empty() ? std::string(field) : cat(light.label, ".", field);
}

// The frames where either of two tracks has a key: between them both are linear (or steps),
// so an inequality between the two that holds at all of them holds at every frame.
std::vector<double> keyFrames(const Track& a, const Track& b) {
  std::vector<double> f;
  for (const Track* t : {&a, &b})
    for (const Track::Key& k : t->keys) f.push_back(k.frame);
  return f;
}

void validateLocal(const Checker& check, RigLocalLight& l) {
  auto origin = [&](const Track& t, const char* field) { return originOf(l, t, field); };
  using T = LocalLight::Type;
  const bool punctual = l.type == T::Point || l.type == T::Spot;
  check.values(l.position, origin(l.position, "position"), Range::Any, 3);
  const char* colorName = l.colorIsPower ? "power" : punctual ? "intensity" : "radiance";
  check.values(l.color, origin(l.color, colorName), Range::NonNegative, 3);
  if (l.type == T::Spot || l.type == T::Disk || l.type == T::Rectangle)
    check.directions(l.direction, origin(l.direction, "direction"));
  if (l.type == T::Rectangle) check.directions(l.up, origin(l.up, "up"));
  if (punctual) check.values(l.range, origin(l.range, "range"), Range::NonNegative, 1);
  if (l.type == T::Spot) {
    check.values(l.innerCone, origin(l.innerCone, "inner_cone"), Range::NonNegative, 1);
    check.values(l.outerCone, origin(l.outerCone, "outer_cone"), Range::OuterCone, 1);
    for (double f : keyFrames(l.innerCone, l.outerCone))
      if (!(l.innerCone.scalarAt(f) < l.outerCone.scalarAt(f)))
        check.fail(origin(l.innerCone, "inner_cone"),
                   cat("the inner cone (", l.innerCone.scalarAt(f), " degrees at frame ", f,
                       ") must be inside the outer cone (", l.outerCone.scalarAt(f), ")"));
  }
  if (l.type == T::Sphere || l.type == T::Disk) check.values(l.radius, origin(l.radius, "radius"), Range::Positive, 1);
  if (l.type == T::Rectangle) {
    check.values(l.width, origin(l.width, "width"), Range::Positive, 1);
    check.values(l.height, origin(l.height, "height"), Range::Positive, 1);
  }
}

}  // namespace

struct LightRig::Cache {
  struct Map {
    ImageRgb image;
    double brightest = 0.0;  // the largest |channel| of any pixel (NaN if any is NaN)
  };
  std::mutex mutex;
  std::map<std::string, Map> maps;                             // by file path
  std::map<std::pair<std::string, int>, sh::ShRgb> projected;  // by (file, bands)
  // Suns split off each map (by file path) and the residual's projections by (file, bands).
  struct Split {
    MapSuns suns;
    ImageRgb residual;
  };
  std::map<std::string, Split> splits;
  std::map<std::pair<std::string, int>, sh::ShRgb> residualProjected;

  // Precondition: the caller holds `mutex`.
  const Split& split(const std::string& file) {
    auto it = splits.find(file);
    if (it != splits.end()) return it->second;
    Split s;
    s.residual = get(file).image;
    double mapLuminance = 0.0;  // of the whole map: what every sun's share is of
    for (int k = 0; k < LightRig::kMaxSunsPerMap; ++k) {
      SunExtraction e = extractSun(s.residual);
      if (k == 0) mapLuminance = luminance(e.mapPower);
      s.suns.reason = e.reason;
      if (!e.sun) break;
      ExtractedSun sun = *e.sun;
      sun.powerShare = mapLuminance > 0.0 ? luminance(sun.power) / mapLuminance : 0.0;
      s.suns.suns.push_back(sun);
      s.residual = std::move(e.residual);
    }
    return splits.emplace(file, std::move(s)).first->second;
  }

  static double brightestOf(const ImageRgb& image) {
    double brightest = 0.0;
    for (const glm::vec3& p : image.pixels)
      for (int c = 0; c < 3; ++c) {
        const double v = std::abs(double(p[c]));
        if (std::isnan(v)) return v;
        brightest = std::max(brightest, v);
      }
    return brightest;
  }

  // Precondition: the caller holds `mutex`.
  const Map& add(const std::string& file, ImageRgb image) {
    const double brightest = brightestOf(image);
    return maps.insert_or_assign(file, Map{std::move(image), brightest}).first->second;
  }

  // The map of `file`, read if not there yet. Precondition: the caller holds `mutex`.
  const Map& get(const std::string& file) {
    auto it = maps.find(file);
    if (it != maps.end()) return it->second;
    // loadHdrImage reads the whole file: a device (/dev/zero) or a FIFO would never end.
    std::error_code ec;
    if (std::filesystem::exists(file, ec) && !std::filesystem::is_directory(file, ec) &&
        !std::filesystem::is_regular_file(file, ec))
      throw Error(cat(file, ": not a regular file"));
    return add(file, loadHdrImage(file));
  }
};

LightRig::LightRig() : cache_(std::make_shared<Cache>()) {}

void LightRig::provideMap(const std::string& file, ImageRgb image) {
  std::lock_guard<std::mutex> lock(cache_->mutex);
  cache_->add(file, std::move(image));
}

void LightRig::validate() {
  Checker check{source.empty() ? std::string() : source + ": "};
  if (lights.empty() && locals.empty()) check.fail("lights", "no lights");
  if (lights.size() + locals.size() > RigLimits::kMaxLights)
    check.fail("lights", cat(lights.size() + locals.size(), " lights (at most ", RigLimits::kMaxLights, ")"));
  for (RigLocalLight& l : locals) validateLocal(check, l);
  if (fps) checkFps(check, *fps);
  for (RigLight& light : lights) {
    auto origin = [&](const Track& t, const char* field) { return originOf(light, t, field); };
    switch (light.type) {
      case RigLight::Type::Environment: {
        check.directions(light.axis, origin(light.axis, "axis"));
        check.values(light.rotation, origin(light.rotation, "rotation"), Range::Any, 1);
        check.values(light.intensity, origin(light.intensity, "intensity"), Range::NonNegative, 3);
        std::lock_guard<std::mutex> lock(cache_->mutex);
        double brightest = 0.0;
        try {
          brightest = cache_->get(light.file).brightest;
        } catch (const Error& e) {
          if (light.label.empty()) throw Error(cat(check.prefix, e.what()));
          check.fail(light.label + ".file", e.what());
        }
        check.mapRadiance(light, brightest, origin(light.intensity, "intensity"));
        break;
      }
      case RigLight::Type::Sun:
      case RigLight::Type::Disk: {
        if (light.useAzimuthElevation) {
          check.values(light.azimuth, origin(light.azimuth, "azimuth"), Range::Any, 1);
          check.values(light.elevation, origin(light.elevation, "elevation"), Range::Elevation, 1);
        } else {
          check.directions(light.direction, origin(light.direction, "direction"));
        }
        Range r = light.type == RigLight::Type::Sun ? Range::SunRadius
                  : light.colorIsIrradiance         ? Range::DiskIrradianceRadius
                                                    : Range::DiskRadius;
        check.values(light.radius, origin(light.radius, "radius"), r, 1);
        const char* colorName =
            light.type == RigLight::Type::Sun || light.colorIsIrradiance ? "irradiance" : "radiance";
        check.values(light.color, origin(light.color, colorName), Range::NonNegative, 3);
        break;
      }
      case RigLight::Type::Uniform:
        check.values(light.color, origin(light.color, "radiance"), Range::NonNegative, 3);
        break;
    }
  }
}

namespace {

// The projection of `file` on `bands` bands, from the cache or computed into it.
// Precondition: the caller holds cache.mutex.
template <class Cache>
const sh::ShRgb& projected(Cache& cache, const std::string& file, int bands) {
  auto key = std::make_pair(file, bands);
  auto it = cache.projected.find(key);
  if (it == cache.projected.end())
    it = cache.projected.emplace(key, projectEnvironment(cache.get(file).image, bands)).first;
  return it->second;
}

}  // namespace

void LightRig::prepare(int bands) const {
  std::lock_guard<std::mutex> lock(cache_->mutex);
  for (const RigLight& light : lights)
    if (light.type == RigLight::Type::Environment) projected(*cache_, light.file, bands);
}

namespace {

// The sun or disk as a direct light at `frame`, if its radius is at most kMaxDirectRadiusDegrees.
std::optional<DirectLight> directLightAt(const RigLight& light, double frame) {
  if (light.type != RigLight::Type::Sun && light.type != RigLight::Type::Disk) return std::nullopt;
  const double degrees = light.radius.scalarAt(frame);
  if (degrees > kMaxDirectRadiusDegrees) return std::nullopt;
  DirectLight d;
  d.direction = light.directionAt(frame);
  d.radius = glm::radians(degrees);
  const glm::dvec3 c = light.color.at(frame);
  const bool isIrradiance = light.type == RigLight::Type::Sun || light.colorIsIrradiance;
  // A disk given by its radiance: E = π L sin² r on a surface facing it (r ≤ 20°, so r < π/2).
  d.irradiance = isIrradiance ? c : c * (kPi * std::sin(d.radius) * std::sin(d.radius));
  return d;
}

}  // namespace

MapSuns LightRig::extractedSuns(size_t index) const {
  const RigLight& light = lights.at(index);
  if (light.type != RigLight::Type::Environment || !light.extractSun) return {};
  std::lock_guard<std::mutex> lock(cache_->mutex);
  return cache_->split(light.file).suns;
}

RigLighting LightRig::evaluateLighting(double frame, int bands) const {
  RigLighting out;
  LightRig rest;  // the lights that stay in SH, sharing this rig's map cache
  rest.cache_ = cache_;
  out.sh = sh::ShRgb(bands);
  out.directSh = sh::ShRgb(bands);
  auto addDirect = [&](const DirectLight& d, size_t source, double share) {
    out.directSh += d.project(bands);
    out.direct.push_back(d);
    out.source.push_back(source);
    out.mapShare.push_back(share);
  };
  for (size_t k = 0; k < lights.size(); ++k) {
    const RigLight& light = lights[k];
    if (std::optional<DirectLight> d = directLightAt(light, frame)) {
      addDirect(*d, k, 0.0);
    } else if (light.type == RigLight::Type::Environment && light.extractSun) {
      // The residual through SH, turned and scaled as the map; each sun turned with the map
      // (light from d in the map comes from R d in the world) and scaled by its intensity.
      sh::ShRgb residual;
      MapSuns suns;
      {
        std::lock_guard<std::mutex> lock(cache_->mutex);
        const Cache::Split& split = cache_->split(light.file);
        suns = split.suns;
        auto key = std::make_pair(light.file, bands);
        auto it = cache_->residualProjected.find(key);
        if (it == cache_->residualProjected.end())
          it = cache_->residualProjected.emplace(key, projectEnvironment(split.residual, bands)).first;
        residual = it->second;
      }
      if (suns.suns.empty()) {
        rest.lights.push_back(light);
        continue;
      }
      const double angle = light.rotation.scalarAt(frame);
      const glm::dmat3 rotation = angle == 0.0 ? glm::dmat3(1.0) : sh::rotationAxis(light.axis.at(frame), angle);
      if (angle != 0.0) residual = sh::Rotation(bands, rotation).apply(residual);
      const glm::dvec3 intensity = light.intensity.at(frame);
      residual *= glm::vec3(intensity);
      out.sh += residual;
      for (const ExtractedSun& sun : suns.suns) {
        DirectLight turned;
        turned.direction = glm::normalize(rotation * sun.direction);
        turned.radius = sun.radius;
        turned.irradiance = sun.irradiance * intensity;
        addDirect(turned, k, sun.powerShare);
      }
    } else {
      rest.lights.push_back(light);
    }
  }
  if (!rest.lights.empty()) out.sh += rest.evaluate(frame, bands);  // windowed below
  sh::applyWindow(out.sh, window);
  sh::applyWindow(out.directSh, window);
  return out;
}

sh::ShRgb LightRig::evaluate(double frame, int bands) const {
  sh::ShRgb sum(bands);
  for (const RigLight& light : lights) {
    switch (light.type) {
      case RigLight::Type::Environment: {
        sh::ShRgb base;
        {
          std::lock_guard<std::mutex> lock(cache_->mutex);
          base = projected(*cache_, light.file, bands);
        }
        const double angle = light.rotation.scalarAt(frame);
        // A zero angle skips the rotation, so an unrotated map is bit-identical to its projection.
        sh::ShRgb env =
            angle == 0.0 ? base : sh::Rotation(bands, sh::rotationAxis(light.axis.at(frame), angle)).apply(base);
        env *= glm::vec3(light.intensity.at(frame));
        sum += env;
        break;
      }
      case RigLight::Type::Sun:
        sum += projectSun(bands, light.directionAt(frame), glm::radians(light.radius.scalarAt(frame)),
                          light.color.at(frame));
        break;
      case RigLight::Type::Disk: {
        const double r = glm::radians(light.radius.scalarAt(frame));
        const glm::dvec3 d = light.directionAt(frame);
        sum += light.colorIsIrradiance ? projectSun(bands, d, r, light.color.at(frame))
                                       : projectDiskRadiance(bands, d, r, light.color.at(frame));
        break;
      }
      case RigLight::Type::Uniform:
        sum += projectUniform(bands, light.color.at(frame));
        break;
    }
  }
  sh::applyWindow(sum, window);
  return sum;
}

RigBackground LightRig::background(double frame) const { return radianceAt(frame, false); }

RigBackground LightRig::shRadiance(double frame) const { return radianceAt(frame, true); }

RigBackground LightRig::radianceAt(double frame, bool shPart) const {
  RigBackground b;
  for (const RigLight& light : lights) {
    switch (light.type) {
      case RigLight::Type::Environment: {
        const ImageRgb* image = nullptr;
        {
          std::lock_guard<std::mutex> lock(cache_->mutex);
          // std::map nodes do not move. The SH part of a map whose suns were split off is its
          // in-painted residual (evaluateLighting's).
          const Cache::Split* split = shPart && light.extractSun ? &cache_->split(light.file) : nullptr;
          image = split && !split->suns.suns.empty() ? &split->residual : &cache_->get(light.file).image;
        }
        const double angle = light.rotation.scalarAt(frame);
        const glm::dmat3 rotation = angle == 0.0 ? glm::dmat3(1.0) : sh::rotationAxis(light.axis.at(frame), angle);
        // Turned by R, the map lights direction d with what it held at R⁻¹ d = Rᵀ d.
        b.maps.push_back(
            {std::shared_ptr<const ImageRgb>(cache_, image), glm::transpose(rotation), light.intensity.at(frame)});
        break;
      }
      case RigLight::Type::Sun:
      case RigLight::Type::Disk: {
        if (shPart && directLightAt(light, frame)) break;  // lit exactly, not through SH
        const double r = glm::radians(light.radius.scalarAt(frame));
        const bool irradiance = light.type == RigLight::Type::Sun || light.colorIsIrradiance;
        if (irradiance && r < kPointSunRadians) break;  // a delta: projectSun's point-sun limit
        const double sin2 = std::sin(r) * std::sin(r);
        const glm::dvec3 c = light.color.at(frame);
        b.caps.push_back({light.directionAt(frame), std::cos(r), irradiance ? c / (kPi * sin2) : c});
        break;
      }
      case RigLight::Type::Uniform:
        b.uniform += light.color.at(frame);
        break;
    }
  }
  return b;
}

glm::dvec3 RigBackground::radiance(const glm::dvec3& d) const {
  glm::dvec3 sum = uniform;
  for (const Map& m : maps) sum += m.scale * sampleEquirect(*m.image, m.worldToMap * d);
  for (const Cap& c : caps)
    if (glm::dot(d, c.direction) >= c.cosRadius) sum += c.radiance;
  return sum;
}

bool LightRig::animated() const {
  for (const RigLight& l : lights)
    for (const Track* t :
         {&l.axis, &l.rotation, &l.intensity, &l.direction, &l.azimuth, &l.elevation, &l.radius, &l.color})
      if (t->animated()) return true;
  for (const RigLocalLight& l : locals)
    for (const Track* t : l.tracks())
      if (t->animated()) return true;
  return false;
}

std::pair<double, double> LightRig::keyRange() const {
  bool any = false;
  double lo = 0.0, hi = 0.0;
  auto widen = [&](const Track* t) {
    if (!t->animated()) return;
    lo = any ? std::min(lo, t->keys.front().frame) : t->keys.front().frame;
    hi = any ? std::max(hi, t->keys.back().frame) : t->keys.back().frame;
    any = true;
  };
  for (const RigLight& l : lights)
    for (const Track* t :
         {&l.axis, &l.rotation, &l.intensity, &l.direction, &l.azimuth, &l.elevation, &l.radius, &l.color})
      widen(t);
  for (const RigLocalLight& l : locals)
    for (const Track* t : l.tracks()) widen(t);
  return {lo, hi};
}

LocalLight RigLocalLight::at(double frame) const {
  LocalLight out;
  out.type = type;
  out.label = label;
  out.position = position.at(frame);
  out.direction = glm::normalize(direction.at(frame));
  out.up = orthogonalTo(out.direction, glm::normalize(up.at(frame)));
  out.range = range.scalarAt(frame);
  out.innerCone = glm::radians(innerCone.scalarAt(frame));
  out.outerCone = glm::radians(outerCone.scalarAt(frame));
  out.radius = radius.scalarAt(frame);
  out.width = width.scalarAt(frame);
  out.height = height.scalarAt(frame);
  const glm::dvec3 c = colorIsPower ? localLightFromPower(out, color.at(frame)) : color.at(frame);
  (out.punctual() ? out.intensity : out.radiance) = c;
  return out;
}

std::vector<const Track*> RigLocalLight::tracks() const {
  return {&position, &direction, &up, &color, &range, &innerCone, &outerCone, &radius, &width, &height};
}

}  // namespace prt
