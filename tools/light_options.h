// Command-line lighting shared by `prt relight`, `prt light` (and later `prt render`).
#pragma once

#include <optional>
#include <string>

#include <CLI/CLI.hpp>
#include <glm/glm.hpp>

#include "prt/sh.h"

namespace prt::tools {

struct LightOptions {
  std::string env;               // equirectangular .exr / .hdr, "" = none
  double envRotate = 0.0;        // degrees about +Y, right-handed
  double envIntensity = 1.0;
  std::vector<double> sunDir;    // towards the sun, world (normalised here)
  std::vector<double> sunIrradiance{1.0, 1.0, 1.0};  // W/m² on a surface facing it
  double sunRadius = 0.265;      // degrees (the real sun's angular radius)
  std::string window = "none";
};

/// Adds --env, --env-rotate, --env-intensity, --sun-dir, --sun-irradiance, --sun-radius, --window.
void addLightOptions(CLI::App& app, LightOptions& o);

/// Projects the lighting onto `bands` bands (sum of all lights, window applied last).
/// Throws prt::Error on bad values or unreadable maps; requires at least one light.
sh::ShRgb buildLight(const LightOptions& o, int bands);

}  // namespace prt::tools
