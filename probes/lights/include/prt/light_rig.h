// Light rigs: several distant lights whose every parameter may change from frame to frame.
//
// A rig is a list of lights (environment maps, suns, disks on the sky, a uniform sky), a
// ringing window and an optional frame rate. Every numeric parameter is a Track: a constant or
// keyframes interpolated per frame. evaluate(frame, bands) sums the lights' SH for a frame:
// environment maps are loaded once and projected once per band count (cached), then rotated
// exactly per frame with sh::Rotation and scaled; analytic lights are projected per frame in
// closed form (prt/light.h). The JSON format is in docs/lights.md ("Light rigs").
//
// Conventions are those of `prt relight`: glTF axes (+Y up), a direction points towards the
// light, rotating the environment by θ about an axis is the right-handed turn of the lighting
// (at +90° about +Y, light that came from +X comes from -Z), and azimuth/elevation place a
// direction as the orbit camera does: (cos el · sin az, sin el, cos el · cos az).
#pragma once

#include <cstddef>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "prt/image.h"
#include "prt/light.h"
#include "prt/local_light.h"
#include "prt/sh.h"
#include "prt/sun_extract.h"

namespace prt {

/// What a rig may hold (docs/lights.md, "Limits"): the readers refuse anything beyond, before
/// allocating for it, and within them every SH a rig evaluates to is finite in float.
struct RigLimits {
  static constexpr size_t kMaxFileBytes = size_t(16) << 20;  // a rig file, or the bytes given
  static constexpr int kMaxJsonDepth = 64;                   // nesting of [ and {
  static constexpr double kMaxValue = 1e12;                  // |every number| (colours, angles, ...)
  static constexpr double kMaxFrame = 1e9;                   // |keyframe numbers|
  static constexpr double kMinFps = 0.001, kMaxFps = 1e4;
  static constexpr size_t kMaxLights = 1024;
  static constexpr size_t kMaxKeys = 100000;       // per parameter
  static constexpr size_t kMaxPathBytes = 4096;    // an environment map's `file`
  static constexpr double kMaxMapRadiance = 1e30;  // brightest map pixel × intensity
};

/// A parameter over frames: one key is a constant, several keys are interpolated.
/// Before the first key the first value holds, after the last key the last value holds.
/// Scalars use value.x (and the CLI and JSON reader store them in all three components).
struct Track {
  enum class Interp {
    Linear,  // straight line between neighbouring keys (directions: slerp, see `direction`)
    Step     // the value of the last key at or before the frame
  };
  struct Key {
    double frame = 0.0;
    glm::dvec3 value{0.0};
  };
  std::vector<Key> keys;  // frames strictly increasing, at least one key
  Interp interp = Interp::Linear;
  /// Unit vectors interpolated along the great circle (slerp) instead of straight lines.
  bool direction = false;
  /// Where the track was written, for messages: "lights[1].radius" (a plain value),
  /// "lights[1].radius.keys" (a key list, then `keyList`), "--sun-radius". Empty: the light's
  /// label and the field name.
  std::string origin;
  bool keyList = false;

  /// A constant track.
  static Track constant(const glm::dvec3& value);
  static Track constant(double value) { return constant(glm::dvec3(value)); }
  /// Linear from v0 at frame f0 to v1 at frame f1 (f0 < f1), or the constant v0 when f0 == f1.
  static Track ramp(double f0, double v0, double f1, double v1);

  /// The value at a (possibly fractional) frame. Precondition: valid (see LightRig::validate).
  glm::dvec3 at(double frame) const;
  double scalarAt(double frame) const { return at(frame).x; }
  bool animated() const { return keys.size() > 1; }
};

/// One distant light of a rig. Which tracks matter depends on the type.
struct RigLight {
  enum class Type { Environment, Sun, Disk, Uniform };
  Type type = Type::Uniform;
  std::string label;  // where it came from, for messages: "rig.json: lights[2]", "--env"

  // Environment: an equirectangular map (docs/lights.md for its orientation), turned by
  // `rotation` degrees about `axis` (right-handed) and multiplied by `intensity` (RGB).
  std::string file;
  Track axis = Track::constant(glm::dvec3(0.0, 1.0, 0.0));  // direction track
  Track rotation = Track::constant(0.0);                    // degrees
  Track intensity = Track::constant(1.0);                   // RGB factor
  /// Split the map's suns off as direct lights (extractSun; docs/lights.md, "Direct lights"):
  /// evaluateLighting lights them exactly and the in-painted residual through SH. JSON
  /// "extract_sun" (default true); evaluate() always projects the whole map.
  bool extractSun = true;

  // Sun and disk: the direction towards the light, either a direction track or
  // azimuth/elevation tracks in degrees (used when `useAzimuthElevation`).
  Track direction = Track::constant(glm::dvec3(0.0, 1.0, 0.0));
  bool useAzimuthElevation = false;
  Track azimuth = Track::constant(0.0);
  Track elevation = Track::constant(90.0);
  Track radius = Track::constant(0.265);  // angular radius, degrees
  // Sun: irradiance on a surface facing it (RGB). Disk: radiance inside the disk, or the
  // irradiance on a surface facing it when `colorIsIrradiance`. Uniform: radiance.
  Track color = Track::constant(1.0);
  bool colorIsIrradiance = false;

  /// Unit direction towards a sun or disk at a frame.
  glm::dvec3 directionAt(double frame) const;
};

/// A light inside the scene in a rig (prt/local_light.h, docs/lights.md "Lights inside the
/// scene"): every parameter a track. With `node`, position, direction and up are in that glTF
/// node's frame and move with it (the scene is known only where the rig is used: the bake
/// resolves the name and refuses one the scene lacks).
struct RigLocalLight {
  LocalLight::Type type = LocalLight::Type::Point;
  std::string label;  // "rig.json: lights[3]"
  std::string node;   // "" = world space
  Track position = Track::constant(0.0);
  Track direction = Track::constant(glm::dvec3(0.0, -1.0, 0.0));  // direction track
  Track up = Track::constant(glm::dvec3(0.0, 0.0, 1.0));          // direction track (rectangle)
  /// Point, spot: intensity (candela); area lights: radiance; or with `colorIsPower`, watts.
  Track color = Track::constant(1.0);
  bool colorIsPower = false;
  Track range = Track::constant(0.0);                                         // metres, 0 = infinite
  Track innerCone = Track::constant(0.0), outerCone = Track::constant(45.0);  // degrees
  Track radius = Track::constant(0.0);                                        // sphere, disk: metres
  Track width = Track::constant(0.0), height = Track::constant(0.0);          // rectangle: metres

  /// The light at a frame, in its node's frame when `node` is set. Precondition: validated.
  LocalLight at(double frame) const;
  /// Every track, for animated() and keyRange().
  std::vector<const Track*> tracks() const;
};

/// Unit direction of azimuth/elevation in degrees: (cos el · sin az, sin el, cos el · cos az).
glm::dvec3 azimuthElevationDirection(double azimuthDegrees, double elevationDegrees);

/// What a camera sees of a rig's lights at one frame: their radiance itself (not its SH
/// projection, and without the rig's window), for backgrounds (docs/lights.md, "Seen by the
/// camera"). Suns of radius 0 (below 10⁻⁶ rad) are deltas and are not seen.
struct RigBackground {
  struct Map {
    std::shared_ptr<const ImageRgb> image;  // equirectangular, oriented as in prt/light.h
    glm::dmat3 worldToMap{1.0};             // the inverse of the light's rotation
    glm::dvec3 scale{1.0};                  // the light's intensity
  };
  /// A sun or disk of non-zero radius: uniform radiance inside the cap dot(d, direction) ≥ cosRadius.
  struct Cap {
    glm::dvec3 direction{0.0, 1.0, 0.0};
    double cosRadius = 1.0;
    glm::dvec3 radiance{0.0};
  };
  std::vector<Map> maps;
  std::vector<Cap> caps;
  glm::dvec3 uniform{0.0};  // the sum of the uniform lights

  /// Radiance arriving from unit direction d (pointing away from the viewer, towards the
  /// light): Σ scale · sampleEquirect(map, worldToMap · d) + the caps containing d + uniform.
  glm::dvec3 radiance(const glm::dvec3& d) const;
};

/// One frame of a rig with its direct lights kept apart (docs/lights.md, "Direct lights"):
/// suns and disks of radius at most kMaxDirectRadiusDegrees. A baked surface then gets
///   E = t · sh + (t − t⁰) · directSh + Σ_direct E_k · visibility-weighted cosine over its cap,
/// t⁰ the direct part of its transfer: sh through the whole transfer, the direct lights' own
/// SH only through the bounced part, their unoccluded light exactly with its shadow.
/// sh + directSh is what evaluate() returns.
struct RigLighting {
  sh::ShRgb sh;        // maps (their residual where suns were split off), uniform lights, larger disks (windowed)
  sh::ShRgb directSh;  // the SH of `direct` (windowed)
  std::vector<DirectLight> direct;
  /// Per entry of `direct`: the index of the rig light it comes from, and for a sun split off
  /// an environment map its share of that map's power (luminance), else 0.
  std::vector<size_t> source;
  std::vector<double> mapShare;
};

/// Suns split off one environment map (LightRig::extractedSuns), in the map's own frame.
struct MapSuns {
  std::vector<ExtractedSun> suns;  // in order of extraction (brightest first)
  std::string reason;              // why extraction stopped
};

/// A set of lights summed, windowed against ringing, with an optional frame rate.
/// Copies share the cache of environment maps. evaluate() may be called from several threads.
class LightRig {
 public:
  std::vector<RigLight> lights;
  /// Lights inside the scene (point, spot, area); they add nothing to the SH light.
  std::vector<RigLocalLight> locals;
  sh::Window window = sh::Window::None;  // applied to the sum, after every light is added
  std::optional<double> fps;             // frames per second, for videos
  std::string source;                    // the rig file, or "" for a rig built in memory

  LightRig();

  /// Uses `image` as the environment map `file` (a RigLight::file) instead of reading that file.
  void provideMap(const std::string& file, ImageRgb image);

  /// Checks every light and track: keys present and increasing, values finite and in range
  /// (radius, intensities >= 0, elevation in [-90, 90], non-zero directions, no opposite
  /// neighbouring direction keys, RigLimits), and loads every environment map not yet loaded
  /// or provided (regular files only; brightest pixel × intensity within limits). Throws
  /// prt::Error "LABEL.field: problem". Interpolated values then stay in range, because every
  /// allowed range is convex. Normalises direction keys.
  void validate();

  /// Projects every environment map onto `bands` bands now (evaluate() would on first use), so
  /// per-frame costs can be measured apart from this one-time cost.
  void prepare(int bands) const;

  /// The rig's SH radiance at `frame` on `bands` bands (sum of all lights, window last).
  /// Precondition: validate() succeeded. Projects each map once per band count (cached).
  sh::ShRgb evaluate(double frame, int bands) const;

  /// The same lights at `frame` with the direct lights apart (RigLighting). The window applies
  /// to both SH parts (it is linear, so their sum is evaluate()'s). Precondition: validate().
  RigLighting evaluateLighting(double frame, int bands) const;

  /// The suns split off environment light `light` (an index into `lights`; extracted once per
  /// map and cached): up to kMaxSunsPerMap, each taken from the residual of the previous one.
  /// Empty for a light with extractSun off. Precondition: validate().
  MapSuns extractedSuns(size_t light) const;
  static constexpr int kMaxSunsPerMap = 4;

  /// What a camera sees of the lights at `frame` (RigBackground). Precondition: validate()
  /// succeeded. The maps are shared with the rig's cache, not copied.
  RigBackground background(double frame) const;

  /// The radiance of the lights that evaluateLighting() puts into its `sh` at `frame`, before the
  /// window: every map (the in-painted residual of one whose suns were split off), the uniform
  /// lights, and the suns and disks too large to be direct lights; the direct lights left out.
  /// What the SH stands for, for estimating what its band limit loses (bake::SkyDetail).
  RigBackground shRadiance(double frame) const;

  /// Whether any parameter changes over frames.
  bool animated() const;
  /// The first and last keyframe over all tracks (0, 0 for a rig without keyframes).
  std::pair<double, double> keyRange() const;

 private:
  RigBackground radianceAt(double frame, bool shPart) const;
  struct Cache;
  std::shared_ptr<Cache> cache_;
};

/// Where a rig read from memory finds its environment maps.
struct RigReadOptions {
  /// Folder that relative map paths are resolved against; "" = none: the rig reads no file at
  /// all, and an environment light must name one of `maps`.
  std::string baseDir;
  /// Maps in memory, by the `file` string exactly as the rig writes it; used before any file.
  std::map<std::string, ImageRgb> maps;
};

/// Parses and validates a rig from its bytes (JSON, docs/lights.md); `name` (the file's path,
/// or any label) starts every message. Checks the bytes first (RigLimits: size, NUL bytes,
/// nesting depth), then every element. Throws prt::Error with one line naming `name` and the
/// JSON path of the problem, e.g. "rig.json: lights[1].radius.keys[2].frame: frames must
/// increase (10 after 12)".
LightRig parseLightRigFromMemory(const std::string& bytes, const std::string& name, const RigReadOptions& options = {});

/// Same from JSON text, relative map paths resolved against `baseDir` ("" = the working folder).
LightRig parseLightRig(const std::string& json, const std::string& name, const std::string& baseDir);

/// Reads and validates a rig file: a regular file of at most RigLimits::kMaxFileBytes, then
/// parseLightRigFromMemory with relative map paths resolved against the rig file's folder.
LightRig loadLightRig(const std::string& path);

}  // namespace prt
