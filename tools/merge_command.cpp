#include "merge_command.h"

#include <cstdio>
#include <limits>

#include "prt/bake/checkpoint.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"

namespace prt::tools {

namespace {

// A checkpoint stage id in words (surface_bake.h, probe_bake.h).
std::string stageName(uint32_t id) {
  if (id == bake::kSurfaceStageDirect) return "direct pass";
  if (id >= bake::kProbeStageFirst) return "probe stage";
  return cat("bounce ", id - 1);
}

}  // namespace

void addMerge(CLI::App& cmd, MergeArgs& a) {
  cmd.add_option("checkpoint", a.checkpoint, "The bake's checkpoint (default of prt bake: OUTPUT.prt-checkpoint)")
      ->required();
  cmd.add_option("--shards", a.shards, "How many shards the stage was baked in (the N of --shard I/N)")
      ->required()
      ->check(CLI::Range(1, 1000000));
  cmd.add_flag("-q,--quiet", a.quiet, "No summary");
}

// mergeShards's stats; a missing shard's message says which `prt bake --shard` to run.
bake::MergeStats merge(const MergeArgs& a) {
  try {
    return bake::mergeShards(a.checkpoint, a.shards);
  } catch (const bake::ShardMissing& e) {
    throw Error(cat(e.what(), ": run prt bake --shard ", e.index, "/", e.count, " first"));
  }
}

int runMerge(const MergeArgs& a) {
  const bake::MergeStats st = merge(a);
  if (a.quiet) return 0;
  std::string stages;
  for (uint32_t id : st.stages) stages += (stages.empty() ? "" : ", ") + stageName(id);
  std::fprintf(stderr, "prt merge: %d shards -> %s: %llu chunk records (%s), %llu state records\n", a.shards,
               a.checkpoint.c_str(), static_cast<unsigned long long>(st.chunkRecords),
               stages.empty() ? "nothing new" : stages.c_str(), static_cast<unsigned long long>(st.stateRecords));
  return 0;
}

}  // namespace prt::tools
