// The command line of every benchmark: CLI11, errors as one line and exit 2, as prt's own.
#pragma once

#include <optional>
#include <string>

#include <CLI/CLI.hpp>

namespace prt::bench {

/// Parses the benchmark's options. nullopt: run; otherwise the status to exit with (--help: 0;
/// a bad command line: one line naming `name`, 2).
inline std::optional<int> parseBenchOptions(CLI::App& app, const std::string& name, int argc, char** argv) {
  app.failure_message([name](const CLI::App*, const CLI::Error& e) { return name + ": " + e.what() + " (see --help)\n"; });
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  return std::nullopt;
}

}  // namespace prt::bench
