// One bake spread over processes (docs/scale.md): MPI ranks (`mpirun -n N prt bake ...`) or
// the shards of a farm without MPI (`prt bake --shard I/N`, then `prt merge`).
//
// Every stage of a bake is split into deterministic chunks (stage_runner.h). MPI ranks that
// share one host take the chunks of a stage as they come free, from a counter in memory they
// share (chunkCounter): a rank slowed by anything else on its core takes fewer, and none waits
// for a slower one at the stage's end. Elsewhere (shards, ranks on several hosts) chunk c
// belongs to rank c mod N. Either way a rank keeps the direct pass's hit records of the chunks
// it computed and gathers those chunks in every bounce. At the end of a stage the ranks
// trade the chunk records the checkpoint already writes (MPI_Allgatherv, or to rank 0 only
// for the probe stage, whose results only the writer needs) and apply the others' chunks as a
// resume restores them: the buffers end up with the bits one process computes.
//
// The process's ranks are set once (RanksScope) by the tool; a library function reads them
// with ranks(). Without a scope: one process, rank 0 of 1. MPI itself is behind this
// interface, in one file (ranks.cpp); a build without MPI has the same code with one rank.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "prt/error.h"

namespace prt::bake {

/// Thrown by a shard once it has saved its share of a stage whose other shares other shards
/// compute: not a failure (`prt merge` joins the shards, and the next run goes on).
class ShardDone : public Error {
 public:
  using Error::Error;
};

/// The processes of one bake.
class Ranks {
 public:
  virtual ~Ranks() = default;
  virtual int rank() const { return 0; }
  virtual int size() const { return 1; }
  /// True: the ranks run together and trade chunk records (MPI). False: each computes its
  /// share of a stage and stops (shards), or there is one process.
  virtual bool exchanges() const { return false; }
  /// Every rank passes `mine`; returns what every rank passed, in rank order. With `toAll`
  /// false only rank 0 receives them (the others get an empty list). Collective.
  virtual std::vector<std::string> gather(std::string mine, bool toAll);
  /// The minimum and the sum of `v` over the ranks. Collective.
  virtual uint64_t minimum(uint64_t v) { return v; }
  virtual uint64_t sum(uint64_t v) { return v; }
  /// Waits for every rank. Collective.
  virtual void barrier() {}
  /// What prt chose of the ranks' transport itself, for the summary; empty when it chose
  /// nothing (one process, shards, or the launcher's or the user's choice).
  virtual std::string transportChoice() const { return {}; }
  /// Does chunk `c` belong to this rank where chunks are split statically? c mod size() == rank().
  bool owns(uint64_t c) const { return int(c % uint64_t(size())) == rank(); }
  /// Counter `slot` (stageCounterSlot, refineCounterSlot) of the next chunk to compute, counted
  /// by all ranks together: ranks on one host share it in memory and take chunks from it with
  /// an atomic add, first come first served. Null where chunks are split statically (owns):
  /// one process, shards, ranks on several hosts, or a slot past kCounterSlots. Starts at 0;
  /// every rank that asks for a slot gets the same counter. A slot serves one loop of a bake.
  virtual uint64_t* chunkCounter(uint32_t slot) {
    (void)slot;
    return nullptr;
  }
  static constexpr uint32_t kCounterSlots = 1024;
  /// Bytes this rank received from other ranks in gather() so far, and the gathers.
  uint64_t bytesReceived() const { return received_; }
  uint64_t gathers() const { return gathers_; }

 protected:
  uint64_t received_ = 0, gathers_ = 0;
};

/// Ranks::chunkCounter's slot of a chunked stage: its checkpoint id modulo 256 (the ids of one
/// bake differ modulo 256: 1 to 66 for the surface stages, 1000 for the probes).
constexpr uint32_t stageCounterSlot(uint32_t stageId) { return stageId % 256; }
/// The slot of refinement's `pass`-th loop shared by the ranks (its points, then per round its
/// new points and its scores); past the last slot the ranks split the loop statically.
constexpr uint32_t refineCounterSlot(uint32_t pass) { return 256 + pass; }

/// The ranks of this process (one process unless a RanksScope says otherwise).
Ranks& ranks();

/// Makes `r` the process's ranks while it lives.
class RanksScope {
 public:
  explicit RanksScope(Ranks* r);
  ~RanksScope();
  RanksScope(const RanksScope&) = delete;
  RanksScope& operator=(const RanksScope&) = delete;

 private:
  Ranks* previous_;
};

/// Shard `index` of `count` (0 <= index < count): computes its share of the first unfinished
/// stage, then stops with ShardDone.
std::unique_ptr<Ranks> shardRanks(int index, int count);

/// True when prt was built with MPI.
bool mpiBuilt();
/// The launcher's rank of this process from its environment (Open MPI's mpirun, PMI), -1 when
/// not launched as one of several ranks. Reads no MPI state.
int launcherRank();
/// Starts MPI when this process is one of several ranks of a launcher (mpirun, srun) and prt
/// was built with MPI; null otherwise (one process). MPI ends when the result is destroyed,
/// unless an exception is unwinding (then stopAllRanks must end the job).
std::unique_ptr<Ranks> startMpi();
/// Ends every rank's process with `code` if MPI runs (MPI_Abort); otherwise returns. For the
/// one place that catches errors, after it has printed the error.
void stopAllRanks(int code);

}  // namespace prt::bake
