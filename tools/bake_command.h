// `prt bake`: per-vertex SH transfer of a glTF scene into a .glb, and optionally a probe grid.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "prt/bake/bounce_operator.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/refine.h"
#include "prt/bake/surface_bake.h"
#include "prt/scene.h"

namespace prt::tools {

struct BakeArgs {
  std::string scene, output;
  std::string probes;  // optional .vdb
  double probeSpacing = 0.0;
  std::vector<int> probeDims;
  std::vector<double> probeBounds;
  int probeSamples = 1024;
  bool probeHalf = false;
  bake::ProbeSettings::Region probeRegion = bake::ProbeSettings::Region::Auto;
  double probeHeight = 4.0;  // auto: kept at most this high above the ground under open sky
  bake::BakeSettings settings;
  bake::RefineSettings refine;
  bool noRefine = false;
  bool noOperator = false;    // no bounce operator in the output (--no-operator)
  bool withOperator = false;  // --operator: deprecated, the operator is the default
  bake::OperatorSettings bounceOperator;
  bool unshadowed = false;
  bool quiet = false;
  bool allowDegenerate = false;  // deprecated --allow-degenerate: dropping them is the default
  LoadOptions load;
  std::string checkpoint;          // default OUTPUT.prt-checkpoint
  double checkpointInterval = 60;  // seconds; 0 = only when interrupted
  bool resume = false;
  std::optional<uint64_t> maxMemory;   // bytes; none: the available memory
  int shardIndex = 0, shardCount = 0;  // --shard I/N; count 0: not a shard
};

/// Adds the options of `prt bake` to its subcommand.
void addBake(CLI::App& cmd, BakeArgs& a);
/// Bakes, with SIGINT/SIGTERM saving a checkpoint. Throws prt::Error on bad input,
/// prt::Interrupted when interrupted.
int runBake(const BakeArgs& a);

}  // namespace prt::tools
