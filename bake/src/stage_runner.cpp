#include "stage_runner.h"

#include <algorithm>
#include <atomic>
#include <chrono>

#include <tbb/parallel_for.h>

#include "prt/error.h"
#include "prt/progress.h"

namespace prt::bake {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace

ThreadLimit::ThreadLimit(int threads) {
  if (threads > 0)
    control_ = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));
}

void stopIfInterrupted(Checkpoint* cp) {
  if (cp) cp->stopIfInterrupted();
  if (interruptRequested()) throw Interrupted("interrupted");
}

ChunkedStage::ChunkedStage(StageSpec spec, Checkpoint* cp) : spec_(std::move(spec)), cp_(cp) {
  PRT_CHECK_GT(spec_.chunkSize, size_t(0));
  done_.assign((spec_.items + spec_.chunkSize - 1) / spec_.chunkSize, 0);
}

void ChunkedStage::restore(const RestoreFn& fn, const std::string& what) {
  if (!cp_) return;
  restoredChunks_ = cp_->restoreChunks(spec_.id, [&](uint64_t c, ByteReader& r) {
    if (c >= chunks()) r.fail(what);
    const Chunk ch = chunk(c);
    fn(ch, r);
    if (!done_[c]) restoredItems_ += ch.end - ch.begin;
    done_[c] = 1;
  });
}

size_t ChunkedStage::chunksLeft() const { return size_t(std::count(done_.begin(), done_.end(), 0)); }

std::vector<uint64_t> ChunkedStage::assignedChunks() const {
  std::vector<uint64_t> mine;
  for (uint64_t c = 0; c < done_.size(); ++c)
    if (!done_[c]) mine.push_back(c);
  return mine;
}

void ChunkedStage::begin(Checkpoint::StageIo io) {
  if (cp_) cp_->beginStage(spec_.id, spec_.label, chunks(), chunks() - chunksLeft(), std::move(io));
}

StageStats ChunkedStage::run(const ChunkFn& fn) {
  const auto t0 = Clock::now();
  const std::vector<uint64_t> mine = assignedChunks();
  std::atomic<uint64_t> rays{0};
  if (!mine.empty()) {
    Progress progress(spec_.name, spec_.items, spec_.unit, spec_.progress);
    size_t left = 0;
    for (uint64_t c : mine) left += chunk(c).end - chunk(c).begin;
    progress.add(spec_.items - left);  // the chunks restored
    tbb::parallel_for(tbb::blocked_range<size_t>(0, mine.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        if (interruptRequested()) continue;
        const Chunk c = chunk(mine[i]);
        const ChunkOutcome outcome = fn(c);
        if (!outcome.finished) continue;  // interrupted: the chunk is done again on resume
        done_[c.index] = 1;
        rays += outcome.rays;
        if (cp_) cp_->complete(c.index);
        progress.add(c.end - c.begin);
      }
    });
    progress.finish();
  }
  stopIfInterrupted(cp_);
  if (cp_) cp_->endStage();
  return StageStats{spec_.name, secondsSince(t0), rays.load()};
}

StageStats runChunkedStage(StageSpec spec, Checkpoint* cp, const ChunkedStage::RestoreFn& restore,
                           Checkpoint::StageIo io, const ChunkedStage::ChunkFn& fn) {
  const auto t0 = Clock::now();
  ChunkedStage stage(std::move(spec), cp);
  stage.restore(restore);
  stage.begin(std::move(io));
  StageStats stats = stage.run(fn);
  stats.seconds = secondsSince(t0);
  return stats;
}

}  // namespace prt::bake
