#include "light_options.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "cli_checks.h"
#include "prt/error.h"

namespace prt::tools {

namespace {

// "DEG" or "START:END" (degrees).
struct Angle {
  double start = 0.0, end = 0.0;
  bool range = false;
};

double parseNumber(const std::string& option, const std::string& text, const std::string& part) {
  char* end = nullptr;
  double v = std::strtod(part.c_str(), &end);
  if (part.empty() || end != part.c_str() + part.size() || !std::isfinite(v))
    throw UsageError(cat(option, " ", text, ": expected DEG or START:END (finite numbers, degrees)"));
  return v;
}

Angle parseAngle(const std::string& option, const std::string& text, bool ranges) {
  Angle a;
  size_t colon = text.find(':');
  if (colon == std::string::npos) {
    a.start = a.end = parseNumber(option, text, text);
    return a;
  }
  if (!ranges)
    throw UsageError(cat(option, " ", text,
                         ": START:END needs a frame range (prt render); give one angle here, "
                         "or a --rig with keyframes and --frame N"));
  a.start = parseNumber(option, text, text.substr(0, colon));
  a.end = parseNumber(option, text, text.substr(colon + 1));
  a.range = true;
  return a;
}

// START:END across the frames: linear from the first frame to the last.
Track angleTrack(const Angle& a, int firstFrame, int lastFrame, const char* option) {
  Track t = a.range ? Track::ramp(firstFrame, a.start, lastFrame, a.end) : Track::constant(a.start);
  t.origin = option;
  return t;
}

glm::dvec3 rgb(const std::vector<double>& v) { return v.size() == 1 ? glm::dvec3(v[0]) : glm::dvec3(v[0], v[1], v[2]); }

Track constantTrack(const glm::dvec3& v, const char* option) {
  Track t = Track::constant(v);
  t.origin = option;
  return t;
}

}  // namespace

void addLightOptions(CLI::App& app, LightOptions& o, bool animated, bool envPositional) {
  o.animated = animated;
  const char* angleForm = animated ? "DEG or START:END (linear across --frames)" : "DEG";
  CLI::Option* rig =
      app.add_option("--rig", o.rig, "Light rig (JSON, keyframed lights; docs/lights.md) instead of --env/--sun-*");
  if (!animated)
    app.add_option("--frame", o.frame, "Frame of the --rig to use (fractional allowed)")
        ->check(finite())
        ->capture_default_str();
  // One option for both spellings, so that --env-rotate and the others see the map either way.
  CLI::Option* env = app.add_option(envPositional ? "env,--env" : "--env", o.env,
                                    "Environment map, equirectangular (.exr or .hdr), linear radiance");
  std::vector<CLI::Option*> envOptions = {app.add_option(
      "--env-rotate", o.envRotate, cat("Turn the environment about --env-axis (right-handed), degrees: ", angleForm))};
  if (animated)
    envOptions.push_back(app.add_option("--env-rotate-end", o.envRotateEnd,
                                        "Rotation at the last frame (same as --env-rotate START:END)")
                             ->check(finite()));
  envOptions.push_back(app.add_option("--env-axis", o.envAxis, "Axis of --env-rotate X,Y,Z (world, glTF axes)")
                           ->delimiter(',')
                           ->expected(3)
                           ->capture_default_str());
  envOptions.push_back(
      app.add_option("--env-intensity", o.envIntensity, "Multiply the environment's radiance: one value or R,G,B")
          ->delimiter(',')
          ->expected(1, 3)
          ->capture_default_str());
  CLI::Option* sunDir = app.add_option("--sun-dir", o.sunDir, "Direction towards the sun X,Y,Z (world, glTF axes)")
                            ->delimiter(',')
                            ->expected(3);
  CLI::Option* sunAzimuth = app.add_option("--sun-azimuth", o.sunAzimuth,
                                           cat("Sun azimuth, degrees: ", angleForm, "; 0 = towards +Z, 90 = +X"));
  CLI::Option* sunElevation = app.add_option("--sun-elevation", o.sunElevation,
                                             cat("Sun elevation, degrees: ", angleForm, "; instead of --sun-dir"));
  // The sun's size and strength need a sun, given either way: checked in buildRig.
  auto sunProperty = [&o](CLI::Option* opt) {
    return opt->each([&o, name = opt->get_name()](const std::string&) {
      if (o.sunOptionGiven.empty()) o.sunOptionGiven = name;
    });
  };
  CLI::Option* sunIrradiance = sunProperty(
      app.add_option("--sun-irradiance", o.sunIrradiance,
                     "Sun irradiance on a surface facing it, R,G,B or one value (W/m², as Blender's strength)")
          ->delimiter(',')
          ->expected(1, 3)
          ->capture_default_str());
  CLI::Option* sunRadius =
      sunProperty(app.add_option("--sun-radius", o.sunRadius, "Angular radius of the sun disk in degrees (0 = a point)")
                      ->capture_default_str());
  app.add_option_function<sh::Window>(
         "--window", [&o](const sh::Window& w) { o.window = w; },
         "Windowing of the light against ringing (default none, or the rig's)")
      ->transform(choice<sh::Window>(
          {{"none", sh::Window::None}, {"hann", sh::Window::Hann}, {"lanczos", sh::Window::Lanczos}}));
  app.add_flag("--no-extract-sun", o.noExtractSun,
               "Leave the suns in environment maps: each map goes whole through the SH transfer instead of its "
               "compact bright sources being lit exactly as direct lights (docs/lights.md)");
  app.add_flag("--no-direct-lights", o.noDirect,
               cat("Light suns and disks of radius <= ", kMaxDirectRadiusDegrees,
                   " degrees through the SH transfer like the rest, instead of exactly with their shadows "
                   "(docs/lights.md, \"Direct lights\")"));
  for (CLI::Option* opt : envOptions) opt->needs(env);
  sunAzimuth->needs(sunElevation);
  sunDir->excludes(sunAzimuth)->excludes(sunElevation);
  for (CLI::Option* opt : envOptions) rig->excludes(opt);
  for (CLI::Option* opt : {env, sunDir, sunAzimuth, sunElevation, sunIrradiance, sunRadius}) rig->excludes(opt);
}

void addGatherOptions(CLI::App& app, GatherOptions& o) {
  app.add_option(
         "--bounce-samples", o.bounceSamples,
         "Rays per baked vertex (the bake's own first rays, traced once) that gather the direct lights' bounced "
         "light and the sky's light beyond the SH band limit where the bake stored no bounce operator (or with "
         "--no-operator; the operator's own count is the bake's, `prt info` shows it); 0: both through the SH "
         "transfer instead")
      ->check(CLI::Range(0, 16777216))
      ->capture_default_str();
  app.add_flag("--no-operator", o.noOperator,
               "Gather the direct lights' bounces and the sky detail by tracing the bake's rays again at start-up "
               "(seconds to minutes on a large scene), instead of through the bounce operator the bake stored "
               "(sparse products per light change; docs/lights.md, \"Their bounces\")");
  app.add_flag("--no-sky-detail", o.noSkyDetail,
               "Light the sky (maps, residuals, uniform skies) through the SH transfer alone, without its light "
               "beyond the band limit gathered over those rays");
}

bake::FrameLightingSettings frameLightingSettings(const LightOptions& light, const GatherOptions& gather) {
  bake::FrameLightingSettings s;
  s.directLights = !light.noDirect;
  s.gatherSamples = gather.bounceSamples;
  s.skyDetail = !gather.noSkyDetail;
  s.useOperator = !gather.noOperator;
  return s;
}

LightRig buildRig(const LightOptions& o, int firstFrame, int lastFrame, bool lightsInScene) {
  LightRig rig;
  if (!o.rig.empty()) {
    rig = loadLightRig(o.rig);
  } else {
    const bool sunByAngles = !o.sunAzimuth.empty() || !o.sunElevation.empty();
    if (o.sunDir.empty() && !sunByAngles && !o.sunOptionGiven.empty())
      throw UsageError(cat(o.sunOptionGiven, " needs a sun: --sun-dir or --sun-elevation"));
    if (o.env.empty() && o.sunDir.empty() && !sunByAngles) {
      if (lightsInScene) {  // the scene's own lights alone
        if (o.window) rig.window = *o.window;
        return rig;
      }
      throw UsageError(
          "no lighting: give --rig RIG.json, or --env MAP and/or a sun (--sun-dir X,Y,Z or --sun-elevation DEG), "
          "or a scene with lights of its own");
    }
    if (!o.env.empty()) {
      RigLight env;
      env.type = RigLight::Type::Environment;
      env.file = o.env;
      Angle rotate = o.envRotate.empty() ? Angle{} : parseAngle("--env-rotate", o.envRotate, o.animated);
      if (!std::isnan(o.envRotateEnd)) {
        if (rotate.range) throw UsageError("--env-rotate-end: --env-rotate already gives START:END");
        rotate.end = o.envRotateEnd;
        rotate.range = true;
      }
      env.rotation = angleTrack(rotate, firstFrame, lastFrame, "--env-rotate");
      env.axis = constantTrack(glm::dvec3(o.envAxis[0], o.envAxis[1], o.envAxis[2]), "--env-axis");
      env.intensity = constantTrack(rgb(o.envIntensity), "--env-intensity");
      rig.lights.push_back(env);
    }
    if (!o.sunDir.empty() || sunByAngles) {
      RigLight sun;
      sun.type = RigLight::Type::Sun;
      sun.colorIsIrradiance = true;
      if (!o.sunDir.empty()) {
        sun.direction = constantTrack(glm::dvec3(o.sunDir[0], o.sunDir[1], o.sunDir[2]), "--sun-dir");
      } else {
        sun.useAzimuthElevation = true;
        sun.azimuth = angleTrack(o.sunAzimuth.empty() ? Angle{} : parseAngle("--sun-azimuth", o.sunAzimuth, o.animated),
                                 firstFrame, lastFrame, "--sun-azimuth");
        sun.elevation = angleTrack(parseAngle("--sun-elevation", o.sunElevation, o.animated), firstFrame, lastFrame,
                                   "--sun-elevation");
      }
      sun.radius = constantTrack(glm::dvec3(o.sunRadius), "--sun-radius");
      sun.color = constantTrack(rgb(o.sunIrradiance), "--sun-irradiance");
      rig.lights.push_back(sun);
    }
    rig.validate();
  }
  if (o.window) rig.window = *o.window;
  if (o.noExtractSun)
    for (RigLight& l : rig.lights) l.extractSun = false;
  return rig;
}

LightRig buildStillRig(const LightOptions& o, bool lightsInScene) {
  // Not ->needs(--rig): --frame 0, the default, is allowed without a rig.
  if (o.rig.empty() && o.frame != 0.0)
    throw UsageError("--frame: needs --rig (the --env/--sun-* shortcuts do not change over frames here)");
  return buildRig(o, 0, 0, lightsInScene);
}

sh::ShRgb buildLight(const LightOptions& o, int bands) { return buildStillRig(o).evaluate(o.frame, bands); }

RigLighting lightingAt(const LightRig& rig, const LightOptions& o, double frame, int bands) {
  return bake::rigLighting(rig, frame, bands, !o.noDirect);
}

RigLighting buildLighting(const LightOptions& o, int bands) { return lightingAt(buildStillRig(o), o, o.frame, bands); }

std::vector<std::string> describeDirectLights(const RigLighting& lighting, const LightRig& rig) {
  std::vector<std::string> out;
  for (size_t k = 0; k < lighting.direct.size(); ++k) {
    const DirectLight& l = lighting.direct[k];
    const double elevation = glm::degrees(std::asin(std::clamp(l.direction.y, -1.0, 1.0)));
    double azimuth = glm::degrees(std::atan2(l.direction.x, l.direction.z));
    if (azimuth < 0.0) azimuth += 360.0;
    char buf[200];
    std::snprintf(buf, sizeof buf, "elevation %.1f°, azimuth %.1f°, radius %.3g°, irradiance (%.4g, %.4g, %.4g)",
                  elevation, azimuth, glm::degrees(l.radius), l.irradiance.r, l.irradiance.g, l.irradiance.b);
    std::string line = buf;
    const RigLight* source = k < lighting.source.size() ? &rig.lights[lighting.source[k]] : nullptr;
    if (source && source->type == RigLight::Type::Environment)
      line += cat(", split off ", std::filesystem::path(source->file).filename().string(), ": ",
                  std::round(1000.0 * lighting.mapShare[k]) / 10.0, "% of its power");
    out.push_back(line);
  }
  return out;
}

std::string describeLocalLight(const LocalLight& l) {
  const size_t colon = l.label.rfind(": ");
  std::string name = colon == std::string::npos ? l.label : l.label.substr(colon + 2);
  char buf[400];
  auto v3 = [](const glm::dvec3& v) {
    char b[100];
    std::snprintf(b, sizeof b, "(%.4g, %.4g, %.4g)", v.x, v.y, v.z);
    return std::string(b);
  };
  std::string line = cat(localLightTypeName(l.type), " ", name, " at ", v3(l.position));
  switch (l.type) {
    case LocalLight::Type::Point:
    case LocalLight::Type::Spot:
      line += cat(", intensity ", v3(l.intensity), " cd");
      if (l.range > 0.0) line += cat(", range ", l.range, " m");
      if (l.type == LocalLight::Type::Spot) {
        std::snprintf(buf, sizeof buf, ", towards %s, cone %.3g..%.3g°", v3(l.direction).c_str(),
                      glm::degrees(l.innerCone), glm::degrees(l.outerCone));
        line += buf;
      }
      break;
    case LocalLight::Type::Sphere:
    case LocalLight::Type::Disk:
      line += cat(", radius ", l.radius, " m");
      if (l.type == LocalLight::Type::Disk) line += cat(", facing ", v3(l.direction));
      line += cat(", radiance ", v3(l.radiance));
      break;
    case LocalLight::Type::Rectangle:
      line += cat(", ", l.width, " x ", l.height, " m, facing ", v3(l.direction), ", radiance ", v3(l.radiance));
      break;
    case LocalLight::Type::Triangle:
      line += cat(", ", localLightArea(l), " m², facing ", v3(l.direction), ", radiance ", v3(l.radiance));
      break;
    case LocalLight::Type::Emitter:
      std::snprintf(buf, sizeof buf, ", %zu triangles, %.4g m², power %s W", l.emitter->triangles.size(),
                    l.emitter->area, v3(l.emitter->power).c_str());
      line += buf;
      break;
  }
  return line;
}

}  // namespace prt::tools
