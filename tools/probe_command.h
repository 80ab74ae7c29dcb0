// `prt probe`: query a probe grid, incident radiance SH and irradiance at points.
#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "light_options.h"

namespace prt::tools {

struct ProbeArgs {
  std::string file, points, output;
  std::vector<double> at, normal;
  LightOptions light;
  std::string scene;           // the baked scene: direct lights traced with their shadows
  int shadowSamples = 64;      // shadow rays per direct light and point
  bool noSceneLights = false;  // --no-scene-lights: the scene's own lights left out
  int threads = 0;
};

/// Adds the options of `prt probe` to its subcommand.
void addProbe(CLI::App& cmd, ProbeArgs& a);
/// Prints JSON for --at, writes the CSV for --points. Throws prt::Error on bad input.
int runProbe(const ProbeArgs& a);

}  // namespace prt::tools
