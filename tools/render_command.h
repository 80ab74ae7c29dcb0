// `prt render`: relit frames of a baked scene, headless (OSMesa or EGL).
#pragma once

#include <CLI/CLI.hpp>

namespace prt::tools {

/// Adds the `render` subcommand; returns it so main can tell whether it was chosen.
CLI::App* addRenderCommand(CLI::App& app);
/// Runs it (after parsing). Throws prt::Error on bad input.
void runRenderCommand();

}  // namespace prt::tools
