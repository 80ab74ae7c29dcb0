// `prt light`: lighting projected to SH, written as JSON.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "light_options.h"

namespace prt::tools {

struct LightArgs {
  std::string output;
  int bands = 3;
  LightOptions light;
};

/// Adds the options of `prt light` to its subcommand.
void addLight(CLI::App& cmd, LightArgs& a);
/// Writes the JSON. Throws prt::Error on bad input.
int runLight(const LightArgs& a);

}  // namespace prt::tools
