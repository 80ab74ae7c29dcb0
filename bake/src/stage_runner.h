// One runner for every chunked stage of a bake (the direct pass, each bounce, the probe
// stage), in the spirit of pbrt-v4's ImageTileIntegrator::Render beside Li: the runner owns
// everything that is not physics (deterministic chunks, TBB threads, restoring finished chunks
// from the checkpoint, registering the stage with it, interrupt polling, progress and timing),
// and a stage hands it a per-chunk function that holds only the estimator.
//
// Determinism: a chunk's result must depend on the chunk alone (its items, the settings and
// the seed), never on the thread that computes it or on the other chunks. The runner may then
// run chunks in any order, restore some from a checkpoint, and (one day) take them from other
// processes, and the stage's buffers end up with the same bits.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <tbb/global_control.h>

#include "prt/bake/checkpoint.h"
#include "prt/bake/surface_bake.h"

namespace prt::bake {

/// Caps the TBB threads of all work done while it lives; 0 leaves every core to TBB.
class ThreadLimit {
public:
  explicit ThreadLimit(int threads);

private:
  std::unique_ptr<tbb::global_control> control_;
};

/// Forgets the checkpoint's stage writers when it goes out of scope: they point into buffers
/// of the function that owns it, which would dangle once it returns or unwinds.
class StageRelease {
public:
  explicit StageRelease(Checkpoint* cp) : cp_(cp) {}
  ~StageRelease() {
    if (cp_) cp_->releaseStages();
  }
  StageRelease(const StageRelease&) = delete;
  StageRelease& operator=(const StageRelease&) = delete;

private:
  Checkpoint* cp_;
};

/// If an interrupt was requested: saves the checkpoint (if any), then throws prt::Interrupted.
void stopIfInterrupted(Checkpoint* cp);

/// Chunk `index` of a stage: its items [begin, end).
struct Chunk {
  uint64_t index = 0;
  size_t begin = 0, end = 0;
};

/// What a chunk function reports: finished = false when it saw an interrupt and gave up (its
/// buffers are then incomplete and the chunk is computed again on resume); the rays it cast.
struct ChunkOutcome {
  bool finished = true;
  uint64_t rays = 0;
};

/// Chunk `index` when `items` fall into chunks of `chunkSize`: items [index·chunkSize,
/// min(items, (index + 1)·chunkSize)). The split depends on nothing else, so a chunk means the
/// same items in every run and on every thread count.
inline Chunk chunkOf(size_t items, size_t chunkSize, uint64_t index) {
  return Chunk{index, size_t(index) * chunkSize, std::min(items, size_t(index + 1) * chunkSize)};
}

struct StageSpec {
  uint32_t id = 0;        // checkpoint stage id
  std::string label;      // names the stage in checkpoint messages: "direct pass"
  std::string name;       // progress bar and StageStats: "direct", "bounce 1"
  std::string unit;       // what the items are: "vertices"
  size_t items = 0;
  size_t chunkSize = 0;   // items per chunk; the last chunk may hold fewer
  bool progress = false;  // progress bar on stderr
};

/// One stage's chunks: which are done, and running the rest.
class ChunkedStage {
public:
  /// Reads one restored chunk record into the stage's buffers.
  using RestoreFn = std::function<void(const Chunk&, ByteReader&)>;
  /// Computes one chunk (called from TBB worker threads, each chunk once).
  using ChunkFn = std::function<ChunkOutcome(const Chunk&)>;

  /// `cp` may be null: no records are restored or written, and an interrupt still stops it.
  ChunkedStage(StageSpec spec, Checkpoint* cp);

  size_t chunks() const { return done_.size(); }
  Chunk chunk(uint64_t index) const { return chunkOf(spec_.items, spec_.chunkSize, index); }
  /// Reads the checkpoint's chunk records of this stage with `fn` (a record whose index is out
  /// of range is a corrupt checkpoint, reported as `what`) and marks them done.
  void restore(const RestoreFn& fn, const std::string& what = "chunk index");
  uint64_t restoredChunks() const { return restoredChunks_; }
  /// Items of the restored chunks.
  size_t restoredItems() const { return restoredItems_; }
  /// Chunks not done yet.
  size_t chunksLeft() const;
  /// The chunks this process computes, in increasing order: today every chunk not done. This
  /// is where chunks would be handed to other processes: a distributed bake would give each
  /// rank its share here and gather the others' chunk records before the next stage.
  std::vector<uint64_t> assignedChunks() const;

  /// Registers the stage with the checkpoint (Checkpoint::beginStage); `io` writes its state
  /// and finished chunks. Call after restore(), before run().
  void begin(Checkpoint::StageIo io);
  /// Runs `fn` on every assigned chunk on TBB threads, skipping all once an interrupt is
  /// requested; reports each finished chunk to the checkpoint and the progress bar. Then stops
  /// if interrupted (saving) and ends the stage. The seconds and rays of this run.
  StageStats run(const ChunkFn& fn);

private:
  StageSpec spec_;
  Checkpoint* cp_;
  std::vector<uint8_t> done_;
  uint64_t restoredChunks_ = 0;
  size_t restoredItems_ = 0;
};

/// A stage whose restored chunks need nothing before it runs: restore, begin, run.
StageStats runChunkedStage(StageSpec spec, Checkpoint* cp, const ChunkedStage::RestoreFn& restore,
                           Checkpoint::StageIo io, const ChunkedStage::ChunkFn& fn);

}  // namespace prt::bake
