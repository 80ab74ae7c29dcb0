// `prt merge`: joins the shards of one bake stage (`prt bake --shard I/N`) into the bake's
// checkpoint, for farms without MPI (docs/scale.md).
#pragma once

#include <string>

#include <CLI/CLI.hpp>

namespace prt::tools {

struct MergeArgs {
  std::string checkpoint;  // the bake's checkpoint (OUTPUT.prt-checkpoint)
  int shards = 0;
  bool quiet = false;
};

/// Adds the options of `prt merge` to its subcommand.
void addMerge(CLI::App& cmd, MergeArgs& a);
/// Merges CHECKPOINT.shard-I-of-N.done (I < N) into CHECKPOINT and deletes them; one summary
/// line on stderr. Throws prt::Error when a shard is missing, unfinished or of another bake.
int runMerge(const MergeArgs& a);

}  // namespace prt::tools
