// The probe bake's stage (prt/bake/probe_bake.h): the lattice laid out and classified
// (placement.cpp), each lattice point baked by the per-probe estimator (tracer.h) in chunks the
// stage runner schedules and checkpoints, and the grid assembled from the chunks' records.
#include "prt/bake/probe_bake.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../stage_runner.h"
#include "placement.h"
#include "prt/error.h"
#include "prt/huge_pages.h"
#include "prt/math.h"
#include "tracer.h"

namespace prt::bake {

namespace {

using namespace probe;

// What the assembly needs of one lattice point besides its transfer; the checkpoint stores it
// as is (no padding, so the record holds no undefined bytes).
struct ProbeSlot {
  uint8_t valid = 0, moved = 0;
  uint8_t outside = 0;  // free, but where no receiver goes: not baked (ProbeSettings::region)
  uint8_t reserved = 0;
  uint32_t traced = 0;  // rays cast for this lattice point: tests, candidates, full set
  glm::vec3 offset{0.0f};
  float skyVisibility = 0.0f;
  std::array<glm::vec2, 6> moments{};
};
static_assert(sizeof(ProbeSlot) == 72 && std::is_trivially_copyable_v<ProbeSlot>);

// The results of every lattice point, in lattice order: what the checkpoint's chunk records
// are written from. Shared with the checkpoint's writer, so a save can never read freed
// memory, whenever it happens.
struct LatticeResults {
  std::vector<ProbeSlot> slots;
  // Per chunk (kProbeChunk points), the transfer of its valid points in lattice order, stride
  // floats each: M (n2² RGB triples), then the upper triangle of its direct part M⁰
  // (n2(n2+1)/2 floats, ProbeGrid::direct's layout). Only valid points hold one: on a sparse
  // level (a closed map keeps a few percent of its lattice) a matrix for every point, written
  // at a few of them, had most of its pages faulted in all the same.
  std::vector<std::vector<float>> chunks;
  size_t stride = 0;
};

// Chunk record: the chunk's slots, then the transfer of its valid points only.
void writeProbeChunk(const LatticeResults& res, const Chunk& c, ByteWriter& w) {
  w.putArray(res.slots.data() + c.begin, c.end - c.begin);
  const std::vector<float>& records = res.chunks[c.index];
  size_t valid = 0;
  for (size_t i = c.begin; i < c.end; ++i) valid += res.slots[i].valid;
  PRT_CHECK_EQ(records.size(), valid * res.stride);
  if (!records.empty()) w.write(records.data(), records.size() * sizeof(float));
}

void readProbeChunk(LatticeResults& res, const Chunk& c, ByteReader& r) {
  r.getArray(res.slots.data() + c.begin, c.end - c.begin);
  size_t valid = 0;
  for (size_t i = c.begin; i < c.end; ++i) {
    const ProbeSlot& slot = res.slots[i];
    if (slot.valid > 1 || slot.moved > 1 || slot.outside > 1 || (slot.valid && slot.outside)) r.fail("probe record");
    valid += slot.valid;
  }
  std::vector<float>& records = res.chunks[c.index];
  records.resize(valid * res.stride);  // read even when empty: a record too short fails
  r.read(records.data(), records.size() * sizeof(float));
}

// Bakes lattice points one at a time: the inside test, relocation, the full set of rays.
struct ProbeBaker {
  const Tracer& tracer;
  const ProbeGrid& grid;
  const ProbeSettings& settings;
  std::vector<glm::dvec3> candidates;

  ProbeBaker(const Tracer& t, const ProbeGrid& g, const ProbeSettings& s)
      : tracer(t), grid(g), settings(s), candidates(relocationCandidates()) {}

  // Lattice point idx into slot and out (n2² RGB floats, then M⁰'s upper triangle); quickFree: its quick inside test
  // (classifyLattice) passed. The double accumulators `acc` live only during this point's
  // trace: the matrix is converted to float at once, with the same per-probe arithmetic in a
  // fixed order, so the result does not depend on threads. False when interrupted first (slot
  // and out are then incomplete).
  bool bake(size_t idx, bool quickFree, ProbeAccum& acc, ProbeSlot& slot, float* out) const {
    const glm::ivec3 dims = grid.dims;
    const glm::ivec3 c = latticeCoord(dims, idx);
    const glm::dvec3 base = grid.latticePosition(c);
    slot = ProbeSlot{};
    glm::dvec3 offset(0.0);
    bool ok = quickFree;  // the quick test, traced by classifyLattice
    for (size_t k = 0; !ok && k < candidates.size(); ++k) {
      ProbeAccum cand;
      glm::dvec3 o = candidates[k] * grid.spacing;
      if (!tracer.trace(glm::vec3(base + o), kProbeTestRays, 2 * idx, false, cand)) return false;
      slot.traced += cand.rays;
      // A moved probe must be clearly outside: half the threshold.
      if (!insideGeometry(cand, 0.5 * settings.insideThreshold)) {
        ok = true;
        offset = o;
        slot.moved = 1;
      }
    }
    const float maxD = tracer.maxDistance;
    slot.moments.fill(glm::vec2(maxD, maxD * maxD));  // "nothing hit", kept by invalid probes
    if (ok) {
      if (!tracer.trace(glm::vec3(base + offset), uint32_t(settings.samples), 2 * idx + 1, true, acc)) return false;
      slot.traced += acc.rays;
      // The full set of rays decides too: the quick test can miss a thin enclosure.
      ok = !insideGeometry(acc, settings.insideThreshold);
    }
    slot.valid = ok;
    slot.offset = glm::vec3(offset);
    if (!ok) return true;
    for (int f = 0; f < 6; ++f)
      if (const uint32_t n = acc.count[f]) {
        double d = 0.0, d2 = 0.0;
        for (int l = 0; l < 8; ++l) {
          d += acc.sumD[size_t(8 * f + l)];
          d2 += acc.sumD2[size_t(8 * f + l)];
        }
        slot.moments[f] = glm::vec2(float(d / n), float(d2 / n));
      }
    slot.skyVisibility = acc.rays ? float(double(acc.escaped) / acc.rays) : 0.0f;
    const double w = 4.0 * kPi / settings.samples;
    const size_t n2 = size_t(acc.n2);
    for (size_t k = 0; k < n2 * n2; ++k) {
      const glm::dvec3 v = w * (glm::dvec3(acc.direct[k]) +
                                glm::dvec3(acc.indirect[3 * k], acc.indirect[3 * k + 1], acc.indirect[3 * k + 2]));
      out[3 * k] = float(v.r);
      out[3 * k + 1] = float(v.g);
      out[3 * k + 2] = float(v.b);
    }
    float* direct = out + 3 * n2 * n2;  // M⁰ is symmetric: its upper triangle, row by row
    for (size_t j = 0; j < n2; ++j)
      for (size_t i = j; i < n2; ++i) *direct++ = float(w * acc.direct[j * n2 + i]);
    return true;
  }
};

// v.resize(n) on huge pages, the new storage faulted in by the workers side by side first: one
// thread's first writes would fault it in alone, a page at a time, while the others wait (on the
// VMs prt is measured on, fresh memory costs about 2 ms a MiB to fault in, on huge pages too).
template <class T>
void resizeFaultedInParallel(std::vector<T>& v, size_t n) {
  PRT_CHECK(v.empty());
  v.reserve(n);
  const size_t bytes = n * sizeof(T), kBlock = size_t(2) << 20;
  char* p = reinterpret_cast<char*>(v.data());
  adviseHugePages(p, bytes);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, (bytes + kBlock - 1) / kBlock, 1),
                    [&](const tbb::blocked_range<size_t>& r) {
                      const size_t begin = r.begin() * kBlock;
                      populatePages(p + begin, std::min(bytes, r.end() * kBlock) - begin);
                    });
  v.resize(n);
}

// Active: valid probes, and invalid ones next to a valid probe (so the file shows where
// interpolation must not read); solid interiors far from free space are not stored. Copies the
// chunks' records into the grid, compacted to the active probes in lattice order: M into
// grid.transfer, M⁰'s triangle into grid.direct (zeros for invalid probes, which have no
// record), each array allocated once at its size, on huge pages, and
// faulted in by the workers together.
void assembleGrid(const std::vector<ProbeSlot>& slots, const std::vector<std::vector<float>>& chunks, size_t stride,
                  ProbeGrid& grid, ProbeStats& stats) {
  const glm::ivec3 dims = grid.dims;
  auto validAt = [&](const glm::ivec3& c) {
    if (glm::any(glm::lessThan(c, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(c, dims))) return false;
    return slots[size_t(c.x) + size_t(dims.x) * (size_t(c.y) + size_t(dims.y) * c.z)].valid != 0;
  };
  std::vector<size_t> activeIdx;  // lattice indices of the active points, in lattice order
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const glm::ivec3 c(x, y, z);
        const size_t idx = size_t(x) + size_t(dims.x) * (size_t(y) + size_t(dims.y) * z);
        bool isActive = slots[idx].valid;
        for (int d = 0; d < 27 && !isActive; ++d)
          isActive = validAt(c + glm::ivec3(d % 3 - 1, (d / 3) % 3 - 1, d / 9 - 1));
        if (isActive) activeIdx.push_back(idx);
      }
  const size_t active = activeIdx.size(), rgb = grid.transferStride(), tri = stride - rgb;
  PRT_CHECK_EQ(tri, ProbeGrid::directStride(grid.bands));
  resizeFaultedInParallel(grid.transfer, active * rgb);  // zeros, kept by invalid probes
  resizeFaultedInParallel(grid.direct, active * tri);
  grid.coord.reserve(active);
  grid.validity.reserve(active);
  grid.offset.reserve(active);
  grid.moments.reserve(active);
  grid.skyVisibility.reserve(active);
  size_t chunk = chunks.size(), at = 0;  // the next valid point's record: chunks[chunk][at]
  for (size_t p = 0; p < active; ++p) {
    const size_t idx = activeIdx[p];
    const ProbeSlot& slot = slots[idx];
    grid.coord.push_back(latticeCoord(dims, idx));
    grid.validity.push_back(slot.valid ? 1.0f : 0.0f);
    grid.offset.push_back(slot.offset);
    grid.moments.push_back(slot.moments);
    grid.skyVisibility.push_back(slot.skyVisibility);
    if (slot.valid) {  // valid points are active: each chunk's records are met in their order
      if (idx / kProbeChunk != chunk) chunk = idx / kProbeChunk, at = 0;
      PRT_CHECK_LE(at + stride, chunks[chunk].size());
      const float* record = chunks[chunk].data() + at;
      at += stride;
      std::copy_n(record, rgb, grid.transfer.begin() + ptrdiff_t(p * rgb));
      std::copy_n(record + rgb, tri, grid.direct.begin() + ptrdiff_t(p * tri));
    }
    stats.active += 1;
    stats.invalid += !slot.valid && !slot.outside;
    stats.valid += slot.valid;
    stats.moved += slot.valid && slot.moved;
  }
  grid.buildIndex();
}

// The grid's lattice and record for these settings, its transfer still to bake.
ProbeGrid layOutGrid(const Scene& scene, const ProbeSettings& settings) {
  ProbeGrid grid;
  grid.bands = settings.bands;
  grid.info.bounces = settings.bounces;
  grid.info.samples = settings.samples;
  grid.info.seed = settings.seed;
  glm::dvec3 lo, hi;
  probeBounds(settings, scene, lo, hi);
  layoutGrid(settings, lo, hi, grid);
  return grid;
}

// What the placement decided, into the stats and the grid's record.
void notePlacement(const LatticeRegion& region, const ProbeSettings& settings, ProbeStats& stats, ProbeGrid& grid) {
  stats.outside = region.outside;
  stats.aboveLevel = region.aboveLevel;
  stats.sealed = region.sealed;
  stats.insideOnly = region.insideOnly;
  grid.info.region = region.insideOnly                                      ? "inside"
                     : settings.region == ProbeSettings::Region::Everywhere ? "everywhere"
                                                                            : "near";
  stats.rays = region.rays;
}

// The lattice points of chunk c: a skipped point's slot marks it, a baked point's transfer goes
// into the chunk's records (LatticeResults::chunks) once the whole chunk is done.
ChunkOutcome bakeChunk(const ProbeBaker& baker, const LatticeRegion& region, LatticeResults& res, const Chunk& c) {
  const float maxD = baker.tracer.maxDistance;
  ProbeAccum acc;  // reused by the probes of this chunk
  ChunkOutcome outcome;
  std::vector<float> records;  // of its valid points
  records.reserve((c.end - c.begin) * res.stride);
  for (size_t idx = c.begin; outcome.finished && idx < c.end; ++idx) {
    ProbeSlot& slot = res.slots[idx];
    if (region.skip[idx]) {
      slot = ProbeSlot{};
      slot.outside = region.free[idx];
      slot.moments.fill(glm::vec2(maxD, maxD * maxD));
      continue;
    }
    const size_t at = records.size();
    records.resize(at + res.stride);
    outcome.finished = baker.bake(idx, region.free[idx] != 0, acc, slot, records.data() + at);
    if (!slot.valid) records.resize(at);
    outcome.rays += slot.traced;
  }
  if (outcome.finished) {
    records.shrink_to_fit();
    res.chunks[c.index] = std::move(records);
  }
  return outcome;
}

// What each point traced beyond its test (ProbeBaker::bake), into stats.traced: a free point its
// full set; any other its candidates' tests until one was free (moved: then its full set from there).
void noteTraced(const LatticeRegion& region, const LatticeResults& res, uint32_t samples, ProbeStats& stats) {
  static_assert(sizeof(ProbeStats::Traced) == 16);  // as the memory estimate counts it
  stats.traced.reserve(res.slots.size());
  for (size_t idx = 0; idx < res.slots.size(); ++idx) {
    if (region.skip[idx]) continue;
    const ProbeSlot& slot = res.slots[idx];
    ProbeStats::Traced t;
    t.lattice = idx;
    t.full = region.free[idx] || slot.moved;
    t.candidates = region.free[idx] ? 0 : (slot.traced - (t.full ? samples : 0)) / kProbeTestRays;
    stats.traced.push_back(t);
  }
}

// The lattice classified and every kept point baked through the stage, on `rays`.
void bakeLattice(const Scene& scene, const std::vector<std::vector<glm::vec3>>& lowerOrder,
                 const ProbeSettings& settings, const RayScene& rays, ChunkedStage& stage, Checkpoint* cp,
                 LatticeResults& res, ProbeGrid& grid, ProbeStats& stats) {
  const AlbedoLookup albedo(scene);
  const double maxSpacing = std::max(grid.spacing.x, std::max(grid.spacing.y, grid.spacing.z));
  std::vector<HalfRows> lowerHalf;
  Tracer tracer{scene, rays, lowerHalf, albedo, settings.bands, settings.seed, float(2.0 * maxSpacing), {}};
  prepare(tracer, lowerOrder, lowerHalf);
  const ProbeBaker baker(tracer, grid, settings);
  // Deterministic and cheap (about kProbeTestRays per point of the lattice, a few percent of
  // the bake), so a resumed bake classifies again rather than storing it.
  const LatticeRegion region = classifyLattice(tracer, grid, settings);
  if (region.interrupted) {
    if (cp) cp->stopIfInterrupted();
    throw Interrupted("interrupted (probe placement)");
  }
  notePlacement(region, settings, stats, grid);
  stats.rays += stage.run([&](const Chunk& c) { return bakeChunk(baker, region, res, c); }).rays;
  stats.traceSeconds = tracer.inEmbree.seconds();
  stats.gatherSeconds = tracer.inGather.seconds();
  noteTraced(region, res, uint32_t(settings.samples), stats);
}

// The origin of a ray set: the lattice point, or its relocation candidate's position, as the
// bake computes it (ProbeBaker::bake, classifyLattice).
glm::vec3 raySetOrigin(const ProbeGrid& layout, const std::vector<glm::dvec3>& candidates, const ProbeRaySet& set) {
  const glm::ivec3 dims = layout.dims;
  const size_t idx = size_t(set.lattice);
  const glm::ivec3 c = latticeCoord(dims, idx);
  const glm::dvec3 base = layout.latticePosition(c);
  if (set.candidate < 0) return glm::vec3(base);
  PRT_CHECK_LT(size_t(set.candidate), candidates.size());
  return glm::vec3(base + candidates[size_t(set.candidate)] * layout.spacing);
}

}  // namespace

// Checkpointing (checkpoint.h): one stage, kProbeStage, of kProbeChunk lattice points per
// chunk in lattice order; a chunk record holds its points' slots and transfer, the very values
// the grid is assembled from, so a resumed bake assembles the same bits.
ProbeGrid bakeProbes(const Scene& scene, const std::vector<std::vector<glm::vec3>>& lowerOrder,
                     const ProbeSettings& settings, ProbeStats* statsOut, Checkpoint* cp, SharedRayScene* shared) {
  validate(settings);
  const auto t0 = std::chrono::steady_clock::now();
  const ThreadLimit threadLimit(settings.threads);
  ProbeGrid grid = layOutGrid(scene, settings);
  const size_t total = size_t(grid.dims.x) * grid.dims.y * grid.dims.z;
  const int n2 = settings.bands * settings.bands;
  auto res = std::make_shared<LatticeResults>();
  res->slots.resize(total);
  res->chunks.resize((total + kProbeChunk - 1) / kProbeChunk);
  res->stride = size_t(n2) * n2 * 3 + ProbeGrid::directStride(settings.bands);

  // The stage's writer holds `res`; forget it however this function ends, so that the
  // checkpoint does not keep the lattice alive (or save chunks of it) after the stage.
  const StageRelease release(cp);
  // Only rank 0 assembles and writes the grid: the other ranks send it their chunks.
  ChunkedStage stage({kProbeStage, "probe stage", "probes", "probes", total, kProbeChunk, settings.progress, false},
                     cp);
  stage.restore([&](const Chunk& c, ByteReader& r) { readProbeChunk(*res, c, r); }, "probe chunk index");
  Checkpoint::StageIo io;
  io.chunksOutliveStage = true;
  io.writeChunk = [res, total](uint64_t c, ByteWriter& w) { writeProbeChunk(*res, chunkOf(total, kProbeChunk, c), w); };
  stage.begin(std::move(io));

  ProbeStats stats;
  stats.probes = total;
  {
    std::optional<RayScene> own;  // without a shared one (BakeControl::rays), built here
    const RayScene& rays = shared ? shared->get() : own.emplace(scene);
    bakeLattice(scene, lowerOrder, settings, rays, stage, cp, *res, grid, stats);
  }
  if (shared) shared->release();  // the last stage that traces: the assembly needs its memory
  if (cp) cp->releaseStages();
  stats.restored = stage.restoredItems();
  if (ranks().rank() != 0) return grid;  // the lattice holds this rank's chunks only
  assembleGrid(res->slots, res->chunks, res->stride, grid, stats);
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (statsOut) *statsOut = stats;
  return grid;
}

void addProbeFingerprint(Fingerprint& fp, const ProbeSettings& s) {
  auto num = [](double v) { return cat(std::setprecision(17), v); };
  auto vec = [&](const std::optional<glm::dvec3>& v) {
    return v ? cat(num(v->x), ",", num(v->y), ",", num(v->z)) : std::string("scene");
  };
  fp.add("probe bands", std::to_string(s.bands));
  fp.add("probe samples", std::to_string(s.samples));
  fp.add("probe bounces", std::to_string(s.bounces));
  fp.add("probe seed", std::to_string(s.seed));
  fp.add("probe spacing", num(s.spacing));
  fp.add("probe dims", cat(s.dims.x, ",", s.dims.y, ",", s.dims.z));
  fp.add("probe bounds min", vec(s.boundsMin));
  fp.add("probe bounds max", vec(s.boundsMax));
  fp.add("probe inside threshold", num(s.insideThreshold));
  fp.add("probe region", s.region == ProbeSettings::Region::Auto         ? "auto"
                         : s.region == ProbeSettings::Region::Everywhere ? "everywhere"
                                                                         : "inside");
  fp.add("probe max height", num(s.maxHeight));
  // Raised whenever the probe bake's arithmetic changes its bits (2: ρ/π in the rows), so that
  // a checkpoint of an earlier build is refused rather than resumed into a grid whose chunks
  // were computed two ways.
  fp.add("probe arithmetic", "2");
}

void probeRaySets(const ProbeStats& stats, uint64_t points, std::vector<ProbeRaySet>& tests,
                  std::vector<ProbeRaySet>& fulls) {
  size_t next = 0;  // stats.traced is in lattice order
  for (uint64_t idx = 0; idx < points; ++idx) {
    tests.push_back({idx, -1});
    if (next == stats.traced.size() || stats.traced[next].lattice != idx) continue;
    const ProbeStats::Traced& t = stats.traced[next++];
    for (uint32_t c = 0; c < t.candidates; ++c) tests.push_back({idx, int(c)});
    if (t.full) fulls.push_back({idx, int(t.candidates) - 1});  // −1 when none was tested
  }
  PRT_CHECK_EQ(next, stats.traced.size());
}

std::vector<Ray> probeTestRays(const ProbeGrid& layout, const ProbeSettings& settings,
                               const std::vector<ProbeRaySet>& sets) {
  const std::vector<glm::dvec3> candidates = relocationCandidates();
  const DirectionKernels& directions = ProbeKernels::active().directions;
  std::vector<Ray> out(sets.size() * kProbeTestRays);
  for (size_t k = 0; k < sets.size(); ++k)
    SphereSet(settings.seed, 2 * sets[k].lattice, directions)
        .fill(out.data() + k * kProbeTestRays, raySetOrigin(layout, candidates, sets[k]), 0, kProbeTestRays);
  return out;
}

std::vector<Ray> probeFullRays(const ProbeGrid& layout, const ProbeSettings& settings,
                               const std::vector<ProbeRaySet>& sets) {
  const std::vector<glm::dvec3> candidates = relocationCandidates();
  const DirectionKernels& directions = ProbeKernels::active().directions;
  const size_t per = size_t(settings.samples);
  std::vector<Ray> out(sets.size() * per);
  for (size_t k = 0; k < sets.size(); ++k) {
    const SphereSet full(settings.seed, 2 * sets[k].lattice + 1, directions);
    const glm::vec3 x = raySetOrigin(layout, candidates, sets[k]);
    for (uint32_t first = 0; first < uint32_t(per); first += kStream)
      full.fill(out.data() + k * per + first, x, first, std::min<uint32_t>(kStream, uint32_t(per) - first));
  }
  return out;
}

}  // namespace prt::bake
