#include "light_options.h"

#include <cmath>

#include "prt/error.h"
#include "prt/image.h"
#include "prt/light.h"

namespace prt::tools {

void addLightOptions(CLI::App& app, LightOptions& o) {
  app.add_option("--env", o.env, "Environment map, equirectangular (.exr or .hdr), linear radiance");
  app.add_option("--env-rotate", o.envRotate, "Rotate the environment by DEG about +Y (right-handed)")
      ->capture_default_str();
  app.add_option("--env-intensity", o.envIntensity, "Multiply the environment's radiance")->capture_default_str();
  app.add_option("--sun-dir", o.sunDir, "Direction towards the sun X,Y,Z (world, glTF axes)")
      ->delimiter(',')->expected(3);
  app.add_option("--sun-irradiance", o.sunIrradiance,
                 "Sun irradiance on a surface facing it, R,G,B or one value (W/m², as Blender's strength)")
      ->delimiter(',')->expected(1, 3)->capture_default_str();
  app.add_option("--sun-radius", o.sunRadius, "Angular radius of the sun disk in degrees (0 = a point)")
      ->capture_default_str();
  app.add_option("--window", o.window, "Windowing of the light against ringing: none, hann, lanczos")
      ->capture_default_str();
}

sh::ShRgb buildLight(const LightOptions& o, int bands) {
  if (o.env.empty() && o.sunDir.empty())
    throw Error("no lighting: give --env MAP and/or --sun-dir X,Y,Z");
  sh::Window window = sh::parseWindow(o.window);
  sh::ShRgb light(bands);
  if (!o.env.empty()) {
    if (!std::isfinite(o.envRotate)) throw Error("--env-rotate: not a finite number");
    if (!std::isfinite(o.envIntensity) || o.envIntensity < 0) throw Error("--env-intensity: must be >= 0");
    ImageRgb map = loadHdrImage(o.env);
    sh::ShRgb env = projectEnvironment(map, bands);
    if (o.envRotate != 0.0) env = sh::Rotation(bands, sh::rotationY(o.envRotate)).apply(env);
    env *= float(o.envIntensity);
    light += env;
  }
  if (!o.sunDir.empty()) {
    glm::dvec3 d(o.sunDir[0], o.sunDir[1], o.sunDir[2]);
    double len = glm::length(d);
    if (!std::isfinite(len) || len == 0.0) throw Error("--sun-dir: must be a non-zero finite direction");
    glm::dvec3 e = o.sunIrradiance.size() == 1 ? glm::dvec3(o.sunIrradiance[0])
                                               : glm::dvec3(o.sunIrradiance[0], o.sunIrradiance[1], o.sunIrradiance[2]);
    if (!std::isfinite(e.x + e.y + e.z) || glm::min(e.x, glm::min(e.y, e.z)) < 0)
      throw Error("--sun-irradiance: values must be finite and >= 0");
    if (!(o.sunRadius >= 0.0 && o.sunRadius < 90.0)) throw Error("--sun-radius: must be in [0, 90) degrees");
    light += projectSun(bands, d / len, glm::radians(o.sunRadius), e);
  }
  sh::applyWindow(light, window);
  return light;
}

}  // namespace prt::tools
