#include "light_options.h"

#include <cmath>
#include <cstdlib>

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
    throw Error(cat(option, " ", text, ": expected DEG or START:END (finite numbers, degrees)"));
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
    throw Error(cat(option, " ", text, ": START:END needs a frame range (prt render); give one angle here, "
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

bool given(const CLI::Option* o) { return o && o->count() > 0; }

}  // namespace

void addLightOptions(CLI::App& app, LightOptions& o, bool animated) {
  o.animated = animated;
  const char* angleForm = animated ? "DEG or START:END (linear across --frames)" : "DEG";
  o.shortcutOptions.clear();
  app.add_option("--rig", o.rig, "Light rig (JSON, keyframed lights; docs/lights.md) instead of --env/--sun-*");
  if (!animated) app.add_option("--frame", o.frame, "Frame of the --rig to use (fractional allowed)")->capture_default_str();
  auto shortcut = [&](CLI::Option* opt) {
    o.shortcutOptions.push_back(opt);
    return opt;
  };
  shortcut(app.add_option("--env", o.env, "Environment map, equirectangular (.exr or .hdr), linear radiance"));
  shortcut(app.add_option("--env-rotate", o.envRotate,
                          cat("Turn the environment about --env-axis (right-handed), degrees: ", angleForm)));
  if (animated)
    shortcut(app.add_option("--env-rotate-end", o.envRotateEnd,
                            "Rotation at the last frame (same as --env-rotate START:END)"));
  shortcut(app.add_option("--env-axis", o.envAxis, "Axis of --env-rotate X,Y,Z (world, glTF axes)")
               ->delimiter(',')->expected(3)->capture_default_str());
  shortcut(app.add_option("--env-intensity", o.envIntensity, "Multiply the environment's radiance: one value or R,G,B")
               ->delimiter(',')->expected(1, 3)->capture_default_str());
  shortcut(app.add_option("--sun-dir", o.sunDir, "Direction towards the sun X,Y,Z (world, glTF axes)")
               ->delimiter(',')->expected(3));
  shortcut(app.add_option("--sun-azimuth", o.sunAzimuth,
                          cat("Sun azimuth, degrees: ", angleForm, "; 0 = towards +Z, 90 = +X")));
  shortcut(app.add_option("--sun-elevation", o.sunElevation,
                          cat("Sun elevation, degrees: ", angleForm, "; instead of --sun-dir")));
  shortcut(app.add_option("--sun-irradiance", o.sunIrradiance,
                          "Sun irradiance on a surface facing it, R,G,B or one value (W/m², as Blender's strength)")
               ->delimiter(',')->expected(1, 3)->capture_default_str());
  shortcut(app.add_option("--sun-radius", o.sunRadius, "Angular radius of the sun disk in degrees (0 = a point)")
               ->capture_default_str());
  o.windowOption = app.add_option("--window", o.window,
                                  "Windowing of the light against ringing: none, hann, lanczos (default none, "
                                  "or the rig's)");
}

LightRig buildRig(const LightOptions& o, int firstFrame, int lastFrame) {
  LightRig rig;
  if (!o.rig.empty()) {
    for (const CLI::Option* opt : o.shortcutOptions)
      if (given(opt))
        throw Error(cat("--rig and ", opt->get_name(), ": give the lights either in the rig file or with --env/--sun-*, "
                        "not both"));
    rig = loadLightRig(o.rig);
  } else {
    auto need = [&](const char* option, const char* what) {
      for (const CLI::Option* opt : o.shortcutOptions)
        if (given(opt) && opt->get_name() == option) throw Error(cat(option, " needs ", what));
    };
    const bool sunByAngles = !o.sunAzimuth.empty() || !o.sunElevation.empty();
    if (o.env.empty()) {
      for (const char* opt : {"--env-rotate", "--env-rotate-end", "--env-axis", "--env-intensity"})
        need(opt, "--env MAP");
    }
    if (o.sunDir.empty() && !sunByAngles)
      for (const char* opt : {"--sun-irradiance", "--sun-radius"}) need(opt, "a sun: --sun-dir or --sun-elevation");
    if (o.env.empty() && o.sunDir.empty() && !sunByAngles)
      throw Error("no lighting: give --rig RIG.json, or --env MAP and/or a sun (--sun-dir X,Y,Z or --sun-elevation DEG)");
    if (!o.env.empty()) {
      RigLight env;
      env.type = RigLight::Type::Environment;
      env.file = o.env;
      Angle rotate = o.envRotate.empty() ? Angle{} : parseAngle("--env-rotate", o.envRotate, o.animated);
      if (!std::isnan(o.envRotateEnd)) {
        if (rotate.range) throw Error("--env-rotate-end: --env-rotate already gives START:END");
        if (!std::isfinite(o.envRotateEnd)) throw Error("--env-rotate-end: not a finite number");
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
        if (sunByAngles) throw Error("--sun-dir: give either --sun-dir or --sun-azimuth/--sun-elevation, not both");
        sun.direction = constantTrack(glm::dvec3(o.sunDir[0], o.sunDir[1], o.sunDir[2]), "--sun-dir");
      } else {
        if (o.sunElevation.empty()) throw Error("--sun-azimuth needs --sun-elevation");
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
  if (!o.window.empty()) rig.window = sh::parseWindow(o.window);
  return rig;
}

LightRig buildStillRig(const LightOptions& o) {
  if (!std::isfinite(o.frame)) throw Error("--frame: not a finite number");
  if (o.rig.empty() && o.frame != 0.0)
    throw Error("--frame: needs --rig (the --env/--sun-* shortcuts do not change over frames here)");
  return buildRig(o, 0, 0);
}

sh::ShRgb buildLight(const LightOptions& o, int bands) { return buildStillRig(o).evaluate(o.frame, bands); }

}  // namespace prt::tools
