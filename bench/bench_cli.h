// The command line of every benchmark: CLI11, errors as one line and exit 2, as prt's own.
#pragma once

#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "prt/bake/kernels.h"

namespace prt::bench {

/// Parses the benchmark's options. nullopt: run; otherwise the status to exit with (--help: 0;
/// a bad command line: one line naming `name`, 2).
inline std::optional<int> parseBenchOptions(CLI::App& app, const std::string& name, int argc, char** argv) {
  app.failure_message(
      [name](const CLI::App*, const CLI::Error& e) { return name + ": " + e.what() + " (see --help)\n"; });
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  return std::nullopt;
}

/// --kernels: which of the bake's kernel paths run. auto: the best this CPU has; avx2 or portable
/// measure, on a CPU with AVX-512, the paths of CPUs without it (the same bits on every path).
inline void addKernelsOption(CLI::App& app, std::string& kernels) {
  app.add_option("--kernels", kernels, "Bake kernels: auto (the best this CPU has), avx2 or portable")
      ->check(CLI::IsMember({"auto", "avx2", "portable"}))
      ->capture_default_str();
}

/// Switches the kernels as --kernels asks; returns the path that runs (avx512, avx2 or portable).
inline std::string applyKernels(const std::string& kernels) {
  bake::setKernels(kernels == "avx2"       ? bake::Kernels::Avx2
                   : kernels == "portable" ? bake::Kernels::Portable
                                           : bake::Kernels::Auto);
  return bake::kernelsName(bake::activeKernels());
}

}  // namespace prt::bench
