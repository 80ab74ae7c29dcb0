// Command-line lighting shared by `prt relight`, `prt light`, `prt probe` and `prt render`.
//
// Either a rig file (--rig, docs/lights.md) or shortcuts (--env..., --sun-...), never both.
// The shortcuts build an in-memory prt::LightRig, so every command lights through one path:
// LightRig::evaluate.
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "prt/bake/frame_lighting.h"
#include "prt/light_rig.h"
#include "prt/sh.h"

namespace prt::tools {

struct LightOptions {
  std::string rig;        // light rig file (JSON), "" = shortcuts
  double frame = 0.0;     // stills (relight, light, probe): the frame of the rig to use
  std::string env;        // equirectangular .exr / .hdr, "" = none
  std::string envRotate;  // "DEG" or "START:END" (render: across the frame range)
  double envRotateEnd = std::numeric_limits<double>::quiet_NaN();  // render: older form of START:END
  std::vector<double> envAxis{0.0, 1.0, 0.0};
  std::vector<double> envIntensity{1.0};             // one value or R,G,B
  std::vector<double> sunDir;                        // towards the sun, world
  std::string sunAzimuth, sunElevation;              // "DEG" or "START:END", degrees
  std::vector<double> sunIrradiance{1.0, 1.0, 1.0};  // W/m² on a surface facing it
  double sunRadius = 0.265;                          // degrees (the real sun's angular radius)
  std::optional<sh::Window> window;                  // none: sh::Window::None, or the rig's
  bool animated = false;                             // START:END allowed (prt render)
  std::string sunOptionGiven;                        // the first of --sun-irradiance, --sun-radius given, if any
  bool noDirect = false;                             // --no-direct-lights: suns and small disks through SH only
  bool noExtractSun = false;                         // --no-extract-sun: environment maps whole through SH
};

/// The gather over the bake's own rays that `prt render` and `prt relight` light baked
/// vertices with (prt/bake/frame_lighting.h): the direct lights' bounces and the sky's detail.
struct GatherOptions {
  int bounceSamples = 256;   // rays per baked vertex; 0: both through the SH transfer
  bool noSkyDetail = false;  // the sky's light beyond the SH band limit left out (the transfer alone)
  bool noOperator = false;   // trace the bake's rays again instead of using its bounce operator
};

/// Adds --rig, --env, --env-rotate, --env-axis, --env-intensity, --sun-dir, --sun-azimuth,
/// --sun-elevation, --sun-irradiance, --sun-radius, --window; with `animated` (prt render)
/// START:END ranges and --env-rotate-end, otherwise --frame; with `envPositional` (prt light) the
/// map may also be given as the positional argument `env`. CLI11 checks what it can state:
/// --rig excludes the shortcuts, the --env-* options need --env, --sun-dir excludes the angles.
void addLightOptions(CLI::App& app, LightOptions& o, bool animated = false, bool envPositional = false);

/// Adds --bounce-samples and --no-sky-detail.
void addGatherOptions(CLI::App& app, GatherOptions& o);

/// The frame lighting of these options; the command sets where direct lights are lit and
/// their shadow rays.
bake::FrameLightingSettings frameLightingSettings(const LightOptions& light, const GatherOptions& gather);

/// The lighting as a validated rig. START:END ranges become keys at firstFrame and lastFrame.
/// Throws UsageError on options that do not go together or do not parse, prt::Error (one line
/// naming the option or file) on a bad rig, map or light.
/// `lightsInScene`: the scene has lights of its own that will light it, so no option is needed
/// (an empty rig then).
LightRig buildRig(const LightOptions& o, int firstFrame, int lastFrame, bool lightsInScene = false);

/// Stills (relight, light, probe): the rig to evaluate at o.frame. Refuses --frame without --rig.
LightRig buildStillRig(const LightOptions& o, bool lightsInScene = false);

/// Stills: the rig's SH at o.frame on `bands` bands.
sh::ShRgb buildLight(const LightOptions& o, int bands);

/// The rig's lighting at `frame` with its direct lights apart (LightRig::evaluateLighting), or,
/// with --no-direct-lights, everything in `sh` and no direct light.
RigLighting lightingAt(const LightRig& rig, const LightOptions& o, double frame, int bands);
/// Stills: lightingAt(buildStillRig(o), o, o.frame, bands).
RigLighting buildLighting(const LightOptions& o, int bands);

/// One line per direct light for a summary: "elevation 35.2°, azimuth 120.0°, radius 0.27°,
/// irradiance (3, 2.9, 2.7)", and for a sun split off a map ", split off sky.hdr: 30.2% of its
/// power".
std::vector<std::string> describeDirectLights(const RigLighting& lighting, const LightRig& rig);

/// One line for a light inside the scene: "point 'Lamp' at (0, 2.5, 0), intensity (80, 80, 80) cd,
/// range 10 m" (the label's file left out).
std::string describeLocalLight(const LocalLight& light);

}  // namespace prt::tools
