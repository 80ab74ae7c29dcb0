// A whole bake in one call (docs/bake.md): a BakeJob says what to bake (scene, settings,
// refinement, probes, outputs, checkpoint, memory limit, shard) and runPipeline does it. It owns
// the processes of the bake (MPI ranks under a launcher, or a shard of a farm: prt/bake/ranks.h),
// the checkpoint of each process, the memory guard (before the work and again on the direct
// pass's pilot), the resume fingerprint, the stage order refine → surface → probes, and the
// outputs with their bake record. A tool parses its options into a job, calls, and reports.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "prt/bake/bounce_operator.h"
#include "prt/bake/checkpoint.h"
#include "prt/bake/memory_estimate.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/refine.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"
#include "prt/scene.h"

namespace prt::bake {

struct BakeOutputs {
  std::string scene;       // the baked .glb
  std::string probes;      // the probe grid's .vdb (with BakeJob::probes), else empty
  bool probeHalf = false;  // the .vdb's grids as 16-bit floats
};

struct JobCheckpoint {
  std::string path;               // empty: BakeOutputs::scene + ".prt-checkpoint"
  double intervalSeconds = 60.0;  // between saves; 0: only when interrupted
  bool resume = false;            // continue the checkpoint of an interrupted bake
  /// Tests: an interrupt once this many chunks have finished in this run, or in the stage
  /// `interruptInStage` (CheckpointOptions).
  uint64_t interruptAfterChunks = 0;
  uint32_t interruptInStage = 0;
};

struct BakeJob {
  std::string scenePath;  // .gltf or .glb; its file name is the record's scene name
  LoadOptions load;
  /// shadowed false: the unshadowed transfer (no rays: no refinement, no checkpoint). progress
  /// is shown by rank 0 only.
  BakeSettings settings;
  RefineSettings refine;  // tolerance 0: no refinement
  /// A probe grid into BakeOutputs::probes. Its bands, bounces, seed, threads and progress
  /// are the surface bake's.
  std::optional<ProbeSettings> probes;
  /// The direct-to-indirect operator stored in the baked scene (prt/bounce_operator.h), built
  /// by the writing process after the transfer; none: the file holds none (its direct lights'
  /// bounces are then gathered by tracing at relight time). Its threads are the bake's.
  std::optional<OperatorSettings> bounceOperator;
  BakeOutputs outputs;
  JobCheckpoint checkpoint;
  std::optional<uint64_t> maxMemory;   // bytes; none: the memory available
  int shardIndex = 0, shardCount = 0;  // shard I of N of a farm; count 0: not a shard
  /// How the memory guard's refusal names the settings (a tool gives its options).
  MemoryAdviceNames memoryNames;
  /// Called once the processes are known (true: this one is an MPI rank), before any file is
  /// touched: where a tool installs its signal handlers.
  std::function<void(bool mpiRank)> started;
  /// Called with the loaded scene before any work: where a tool prints its warnings.
  std::function<void(const Scene&)> loaded;
};

struct BakeReport {
  enum class Outcome {
    Written,           // the outputs are in place (this process wrote them)
    OtherRank,         // an MPI rank other than 0: its share is done, rank 0 wrote
    ShardSaved,        // a shard saved its share of a stage into `shardFile` + ".done"
    ShardAlreadyDone,  // a shard found its share done already (`shardFile` + ".done")
  };
  Outcome outcome = Outcome::Written;
  std::string checkpointPath;  // the bake's checkpoint (a shard's share is saved apart)
  std::string shardFile;       // a shard's own checkpoint
  std::string shardStage;      // ShardSaved: what was saved ("direct pass: chunks ...")

  Scene scene;            // Written: the baked (refined) scene, with its transfer
  BakeSettings settings;  // as baked
  RefineSettings refine;  // as applied (tolerance 0: none)
  RefineStats refined;
  BakeStats surface;
  ProbeStats probes;        // with BakeJob::probes
  uint64_t probeBytes = 0;  // the .vdb's size
  struct Operator {
    bool built = false;
    double seconds = 0.0;
    uint64_t bytes = 0;  // packed
    uint32_t clusters = 0;
    uint64_t vertexEntries = 0, clusterEntries = 0;
    uint64_t probeEntries = 0;  // of the probes' rows (0 without probes)
  } bounceOperator;
  MemoryEstimate memory;  // the last estimate the guard checked
  double writeSeconds = 0.0;
  // The processes: MPI ranks (with what rank 0 received), else one.
  bool mpi = false;
  int ranks = 1;
  std::string transportChoice;
  uint64_t bytesReceived = 0, gathers = 0;
};

/// A refusal whose remedy is one of the job's settings, so that a tool can say it in its own
/// options (what() says it in the library's terms).
class BakeRefused : public Error {
 public:
  enum class Reason {
    MpiNotBuilt,      // started as an MPI rank by a prt built without MPI: bake in shards
    ShardUnderMpi,    // a shard asked for under an MPI launcher
    CheckpointFound,  // a fresh bake found an interrupted bake's checkpoint at path(): resume it
    ShardsMerged,     // a shard found every stage merged at path(): resume instead
  };
  BakeRefused(Reason reason, std::string path, const std::string& what)
      : Error(what), reason_(reason), path_(std::move(path)) {}
  Reason reason() const { return reason_; }
  const std::string& path() const { return path_; }

 private:
  Reason reason_;
  std::string path_;
};

/// Thrown when a bake with a checkpoint is interrupted, once the checkpoint is saved: "interrupted:
/// checkpoint saved to PATH (bounce 1 40% done)". Resuming continues it.
class InterruptedAndSaved : public Interrupted {
 public:
  using Interrupted::Interrupted;
};

/// Runs the job: refine → surface → probes, checkpointed, under the memory guard, in this
/// process's share of the ranks; writes the outputs (rank 0 of MPI ranks; a shard writes none)
/// and removes the checkpoint once they are in place. Throws prt::Error on bad input (the
/// settings, the scene, an unwritable output: before the work), BakeRefused, InterruptedAndSaved,
/// prt::Interrupted when interrupted without a checkpoint.
BakeReport runPipeline(const BakeJob& job);

/// What must match for a checkpoint to be resumed: the scene's content and every setting that
/// changes the output bits (not threads, not progress).
Fingerprint bakeFingerprint(const Scene& scene, const BakeSettings& settings, const RefineSettings& refine,
                            const ProbeSettings* probes, bool probeHalf);

}  // namespace prt::bake
