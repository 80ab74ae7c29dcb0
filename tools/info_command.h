// `prt info`: describe baked or input files (glTF scenes, probe grids), in the spirit of vdb_print.
#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace prt::tools {

struct InfoArgs {
  std::vector<std::string> files;
};

/// Adds the options of `prt info` to its subcommand.
void addInfo(CLI::App& cmd, InfoArgs& a);
/// Describes each file on stdout; a file that cannot be described is one line on stderr and
/// the next is still described. Returns 1 if any failed, else 0.
int runInfo(const InfoArgs& a);

}  // namespace prt::tools
