// `prt relight`: per-vertex exitant radiance of a baked scene under new light, as _RADIANCE
// (COLOR_0 holds it clamped to 0..1 for viewers).
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "light_options.h"

namespace prt::tools {

struct RelightArgs {
  std::string baked, output, csv;
  LightOptions light;
  int shadowSamples = 64;  // shadow rays per direct light and vertex
  GatherOptions gather;
  int threads = 0;
  bool noSceneLights = false;  // --no-scene-lights: the file's own lights left dark
  bool quiet = false;
};

/// Adds the options of `prt relight` to its subcommand.
void addRelight(CLI::App& cmd, RelightArgs& a);
/// Writes the lit scene (and the CSV). Throws prt::Error on bad input.
int runRelight(const RelightArgs& a);

}  // namespace prt::tools
