// Per-vertex transfer to irradiance (docs/prt-math.md):
//
//   t⁰_i(x) = ∫ V(x,ω) y_i(ω) max(N·ω, 0) dω
//   t^k(x)  = ∫ (1 − V(x,ω)) (ρ(h)/π) t^{k−1}(h(ω)) max(N·ω, 0) dω,   t = Σ_k t^k
//
// Monte Carlo with cosine-weighted directions (pdf max(N·ω,0)/π), N samples per vertex:
//   t⁰_i ≈ (π/N) Σ_s V_s y_i(ω_s)
//   t^k  ≈ (1/N) Σ_{s hits} ρ(h_s) t^{k−1}(h_s)        (π · (ρ/π) = ρ; no y_i: a diffuse hit
//                                                        point sends the same radiance along ω)
// The rays of the direct pass are traced once; each hit on a front face is kept as a compact
// record (triangle, barycentrics), and every bounce is a gather over those records: a sparse
// matrix-vector product, no new rays. Back-face hits on a one-sided surface block light and
// send none (its back has no transfer).
//
// Double-sided materials: both sides of a vertex receive light and reflect it. The back side of
// each vertex of a double-sided instance is an extra "virtual vertex" of the layout (normal −n,
// rays leaving from the back, its own ray stream), numbered after every real vertex so that
// the real vertices' numbering, chunks and ray streams are those of a one-sided bake; the back
// faces of its triangles are extra "virtual triangles" whose corners are those virtual
// vertices. A ray that hits the back of a double-sided face is recorded as a hit on the
// virtual triangle, so the bounces gather the back side's transfer with the same record format,
// and the direct pass and every bounce treat virtual vertices like any other.
#include "prt/bake/surface_bake.h"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

#include <immintrin.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "half_rows.h"
#include "prt/bake/kernels.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/sampling.h"
#include "prt/error.h"
#include "prt/math.h"
#include "prt/sh.h"
#include "stage_runner.h"
#include "surface_layout.h"
#include "trace_clock.h"
#include "vertex_rays.h"

namespace prt::bake {

namespace {

using Clock = std::chrono::steady_clock;

// Rays per Embree stream: enough to amortise the call, small enough to stay in cache.
constexpr int kStream = 256;
// Vertices per task: the unit of parallel work and of hit-record storage.
constexpr size_t kChunk = 64;

}  // namespace

namespace {

// The closed form, for the front side and (`bothSides`) then the back side (normal −n).
std::vector<glm::vec3> unshadowedTransfer(const MeshInstance& m, int bands, bool bothSides) {
  const int n2 = bands * bands;
  const size_t n = m.vertexCount();
  std::vector<glm::vec3> t((bothSides ? 2 : 1) * n * n2);
  float y[sh::kMaxBands * sh::kMaxBands];
  for (size_t w = 0; w < t.size() / n2; ++w) {
    const size_t v = w % n;
    sh::evaluate(bands, w < n ? m.normals[v] : -m.normals[v], y);
    for (int l = 0; l < bands; ++l) {
      float a = float(sh::clampedCosineFactor(l));
      for (int mm = -l; mm <= l; ++mm) t[w * n2 + sh::index(l, mm)] = glm::vec3(a * y[sh::index(l, mm)]);
    }
  }
  return t;
}

// An upper bound on the share of direct rays that are kept as hit records (a front face, or
// the back of a double-sided face), from a pilot: the first
// kPilotRays rays (a stratified Sobol prefix of the bake's own rays) of up to kPilotVertices
// vertices spread evenly over the scene. The bound is the mean share plus 3 standard errors
// of the per-vertex shares plus 0.02 for the difference between a 64-ray prefix and all N
// rays, capped at 1: the memory guard needs a bound, not an estimate.
double pilotFrontHitShare(const Scene& scene, const Layout& lay, const RayScene& rays,
                          const std::vector<glm::vec3>& origins, const BakeSettings& settings, float tnear) {
  constexpr size_t kPilotVertices = 2048;
  constexpr uint32_t kPilotRays = 64;
  const size_t m = std::min(lay.vertices, kPilotVertices);
  const uint32_t p = std::min<uint32_t>(uint32_t(settings.samples), kPilotRays);
  if (m == 0) return 0.0;
  std::vector<double> share(m);
  tbb::parallel_for(size_t(0), m, [&](size_t i) {
    const size_t v = i * lay.vertices / m;
    const VertexSampler sampler(origins[v], normalOf(scene, lay, v), settings.seed, v, tnear);
    alignas(64) Ray batch[kPilotRays];
    for (uint32_t j = 0; j < p; ++j) sampler.make(j, batch[j]);
    rays.intersect(batch, p);
    uint32_t front = 0;
    for (uint32_t j = 0; j < p; ++j) front += batch[j].hit() && recordedTriangle(lay, batch[j]) != Layout::kNone;
    share[i] = double(front) / p;
  });
  double mean = 0, var = 0;
  for (double s : share) mean += s;
  mean /= double(m);
  for (double s : share) var += (s - mean) * (s - mean);
  var /= double(std::max<size_t>(m - 1, 1));
  return std::min(1.0, mean + 3.0 * std::sqrt(var / double(m)) + 0.02);
}

// A triangle's corners (global vertices) and instance, read together by the gather.
struct TriCorners {
  uint32_t v[3];
  uint32_t mesh;
};

// What the stages of one surface bake share: the layout, the settings, and the buffers each
// stage hands to the next (values = vertices × n2 RGB, in the layout's vertex order).
struct SurfaceBake {
  const Scene& scene;
  const BakeSettings& settings;
  const Layout& lay;
  int n2;
  size_t values;
  uint32_t N;     // samples per vertex
  bool keepHits;  // bounces follow: keep the direct pass's hit records
  int bounces;
  uint32_t stageDone;  // checkpoint stage id of the finished surface stage
  std::vector<ChunkHits> chunkHits;
  // Per chunk: this rank holds its hit records (it computed the chunk in the direct pass, or
  // restored it from its checkpoint), so it gathers the chunk in every bounce.
  std::vector<uint8_t> holds;
  // t⁰, colourless: values floats (the direct part the files keep apart from the total).
  std::vector<float> direct;
  std::vector<glm::vec3> total, lowerOrder;
  // t^{k−1} as bounce k starts, then t^k: the gather reads t^{k−1} only as `half` and writes
  // each vertex's t^k over its t^{k−1}, so one buffer holds both orders.
  std::vector<glm::vec3> order;
  HalfRows half;                    // t^{k−1} as halves, during bounce k (half_rows.h)
  std::vector<TriCorners> corners;  // per triangle, during the bounces
  uint64_t hitCount = 0;
  uint32_t gatherRays, gatherWords;  // BakeSettings::keepGatherRays, where hits are kept

  SurfaceBake(const Scene& sc, const BakeSettings& s, const Layout& l)
      : scene(sc),
        settings(s),
        lay(l),
        n2(s.bands * s.bands),
        values(l.vertices * n2),
        N(uint32_t(s.samples)),
        keepHits(s.bounces > 0),
        bounces(keepHits ? s.bounces : 0),
        stageDone(uint32_t(2 + bounces)),
        chunkHits(keepHits ? (l.vertices + kChunk - 1) / kChunk : 0),
        holds(chunkHits.size(), 0),
        gatherRays(keepHits ? uint32_t(std::min(s.keepGatherRays, s.samples)) : 0),
        gatherWords((gatherRays + 63) / 64) {}

  Chunk chunk(uint64_t c) const { return chunkOf(lay.vertices, kChunk, c); }
  StageSpec spec(uint32_t id, const std::string& label, const std::string& name) const {
    return StageSpec{id, label, name, "vertices", lay.vertices, kChunk, settings.progress};
  }
  void countHits() {
    hitCount = 0;
    for (const ChunkHits& ch : chunkHits) hitCount += ch.hits.size();
  }
};

// ---- The direct pass of one chunk: t⁰_i ≈ (π/N) Σ_s V_s y_i(ω_s), and the front-face hits.
struct DirectPass {
  SurfaceBake& b;
  const RayScene& rays;
  const std::vector<glm::vec3>& origins;
  float tnear;
  TraceClock& inEmbree;  // all threads' time inside Embree's calls (StageStats::traceSeconds)

  ChunkOutcome operator()(const Chunk& c) const {
    alignas(64) Ray batch[kStream];
    double acc[sh::kMaxBands * sh::kMaxBands];
    float y[sh::kMaxBands * sh::kMaxBands];
    const int n2 = b.n2;
    const uint32_t N = b.N;
    ChunkHits* ch = b.keepHits ? &b.chunkHits[c.index] : nullptr;
    // The chunk's hit records go to a buffer of this thread's that keeps its capacity from
    // chunk to chunk (reserved for the chunk's bound, every ray a hit, up to kScratchHits), and
    // are copied once, at the end, into a vector of their count. Pushed into the chunk's own
    // vector they were copied two or three times, each time into fresh pages (memmove and its
    // page faults: 7% of a profile of the room's bake; the one copy left still faults its
    // destination in, docs/bake.md "Page faults").
    constexpr size_t kScratchHits = size_t(1) << 20;  // 8 MiB; beyond, the buffer grows as needed
    thread_local std::vector<HitRecord> hits;
    const uint32_t words = b.gatherWords;
    if (ch) {
      ch->begin.assign(1, 0);
      ch->gatherBits.assign(words ? (c.end - c.begin) * 2 * words : 0, 0);
      hits.clear();
      hits.reserve(std::min(kScratchHits, (c.end - c.begin) * size_t(N)));
    }
    for (size_t v = c.begin; v < c.end; ++v) {
      if (interruptRequested()) {  // a chunk can take long at a huge sample count
        if (ch) *ch = ChunkHits{};
        return {false, 0};
      }
      const VertexSampler sampler(origins[v], normalOf(b.scene, b.lay, v), b.settings.seed, v, tnear);
      std::fill_n(acc, n2, 0.0);
      for (uint32_t first = 0; first < N; first += kStream) {
        const uint32_t count = std::min<uint32_t>(kStream, N - first);
        for (uint32_t j = 0; j < count; ++j) sampler.make(first + j, batch[j]);
        inEmbree.time([&] {
          if (ch)
            rays.intersect(batch, count);
          else
            rays.occluded(batch, count);
        });
        uint64_t* bits = words ? &ch->gatherBits[(v - c.begin) * 2 * words] : nullptr;
        for (uint32_t j = 0; j < count; ++j) {
          const Ray& ray = batch[j];
          const bool blocked = ch ? ray.hit() : ray.occludedHit();
          const uint32_t r = first + j;
          const bool gathered = bits && r < b.gatherRays;
          if (!blocked) {
            sh::evaluate(b.settings.bands, ray.dir, y);
            for (int i = 0; i < n2; ++i) acc[i] += y[i];
            if (gathered) bits[r / 64] |= uint64_t(1) << (r % 64);
          } else if (ch) {
            const uint32_t tri = recordedTriangle(b.lay, ray);
            if (tri == Layout::kNone) continue;
            hits.push_back({tri, quantise(ray.u), quantise(ray.v)});
            if (gathered) bits[words + r / 64] |= uint64_t(1) << (r % 64);
          }
        }
      }
      const double w = kPi / N;
      for (int i = 0; i < n2; ++i) b.direct[v * n2 + i] = float(acc[i] * w);
      if (ch) ch->begin.push_back(uint32_t(hits.size()));
    }
    if (ch) {
      ch->hits.assign(hits.begin(), hits.end());
      b.holds[c.index] = 1;
    }
    return {true, uint64_t(c.end - c.begin) * N};
  }
};

// ---- One bounce of one chunk: t^k ≈ (1/N) Σ_{s hits} ρ(h_s) t^{k−1}(h_s), over the hit records.
//
// A bounce is memory-bound: each record reads its triangle's corners and their three rows of
// t^{k−1} (3·n2 floats each), rows that lie anywhere in an array far larger than the caches.
// So the gather reads t^{k−1} as halves (HalfRows: 3·n2 halves a row, padded to whole cache
// lines, one line at 3 bands instead of two or three), a triangle's corners and instance
// from one 16-byte entry (TriCorners), and prefetches both some records ahead. A half carries
// a relative rounding error of at most 2⁻¹¹ ≈ 4.9e-4 (docs/bake.md, "Speed": what it changes).
constexpr uint32_t kAheadCorners = 16, kAheadRows = 8;  // records ahead, measured on the room

std::vector<TriCorners> triCorners(const Layout& lay) {
  std::vector<TriCorners> c(lay.triangles);
  for (size_t t = 0; t < lay.triangles; ++t)
    c[t] = {{lay.triVerts[3 * t], lay.triVerts[3 * t + 1], lay.triVerts[3 * t + 2]}, lay.meshOfTri[t]};
  return c;
}

// One record's weights: barycentrics and base colour.
struct RecordWeights {
  float b0, b1, b2;
  glm::vec3 rho;
  const TriCorners* corners;
};

// A record's weights; the colour of an instance whose colour varies is the next of `varying`
// (started on the vertex's records).
inline RecordWeights weightsOf(const SurfaceBake& b, const AlbedoLookup& albedo, const HitRecord& rec,
                               VaryingColours& varying) {
  RecordWeights w;
  w.b1 = rec.b1 * (1.0f / 65535.0f);
  w.b2 = rec.b2 * (1.0f / 65535.0f);
  w.b0 = 1.0f - w.b1 - w.b2;
  w.corners = &b.corners[rec.tri];
  const uint32_t mesh = w.corners->mesh;
  w.rho = albedo.uniform[mesh] ? albedo.constant[mesh] : varying.next();
  return w;
}

// Always inlined, as prefetchLines (half_rows.h) says.
[[gnu::always_inline]] inline void prefetchAhead(const SurfaceBake& b, const HitRecord* hits, uint32_t h,
                                                 uint32_t end) {
  if (h + kAheadCorners < end) __builtin_prefetch(&b.corners[hits[h + kAheadCorners].tri]);
  if (h + kAheadRows < end) {
    const TriCorners& c = b.corners[hits[h + kAheadRows].tri];
    for (uint32_t k = 0; k < 3; ++k) prefetchLines(b.half.row(c.v[k]), b.half.stride * sizeof(uint16_t));
  }
}

// Without F16C: the same operations lane by lane (lane i of a row is RGB channel i % 3 of
// coefficient i / 3), so both paths give the same bits.
void gatherChunkPortable(SurfaceBake& b, const AlbedoLookup& albedo, const Chunk& c) {
  const int lanes = 3 * b.n2;
  const ChunkHits& ch = b.chunkHits[c.index];
  const HitRecord* hits = ch.hits.data();
  const uint32_t end = uint32_t(ch.hits.size());
  float acc[3 * sh::kMaxBands * sh::kMaxBands];
  const float w = 1.0f / float(b.N);
  thread_local VaryingColours colours;
  for (size_t v = c.begin; v < c.end; ++v) {
    std::fill_n(acc, lanes, 0.0f);
    const uint32_t first = ch.begin[v - c.begin], last = ch.begin[v - c.begin + 1];
    if (albedo.varies) colours.start(albedo, b.lay, hits, first, last);
    for (uint32_t h = first; h < last; ++h) {
      prefetchAhead(b, hits, h, end);
      const RecordWeights r = weightsOf(b, albedo, hits[h], colours);
      const uint16_t* t0 = b.half.row(r.corners->v[0]);
      const uint16_t* t1 = b.half.row(r.corners->v[1]);
      const uint16_t* t2 = b.half.row(r.corners->v[2]);
      for (int i = 0; i < lanes; ++i) {
        float s = floatFromHalf(t0[i]) * r.b0;
        s = s + floatFromHalf(t1[i]) * r.b1;
        s = s + floatFromHalf(t2[i]) * r.b2;
        acc[i] += s * r.rho[i % 3];
      }
    }
    float* out = &b.order[v * size_t(b.n2)].x;
    for (int i = 0; i < lanes; ++i) out[i] = acc[i] * w;
  }
}

// With F16C: 8 lanes at a time, K vectors a row; ρ's channels repeat every 3 vectors.
template <int K>
__attribute__((target("avx2,f16c"))) void gatherChunkF16c(SurfaceBake& b, const AlbedoLookup& albedo, const Chunk& c) {
  const int lanes = 3 * b.n2;
  const ChunkHits& ch = b.chunkHits[c.index];
  const HitRecord* hits = ch.hits.data();
  const uint32_t end = uint32_t(ch.hits.size());
  alignas(32) float sum[8 * K];
  const float w = 1.0f / float(b.N);
  thread_local VaryingColours colours;
  for (size_t v = c.begin; v < c.end; ++v) {
    __m256 acc[K];
    for (int k = 0; k < K; ++k) acc[k] = _mm256_setzero_ps();
    const uint32_t first = ch.begin[v - c.begin], last = ch.begin[v - c.begin + 1];
    if (albedo.varies) colours.start(albedo, b.lay, hits, first, last);
    for (uint32_t h = first; h < last; ++h) {
      prefetchAhead(b, hits, h, end);
      const RecordWeights r = weightsOf(b, albedo, hits[h], colours);
      const float cr = r.rho.r, cg = r.rho.g, cb = r.rho.b;
      const __m256 rho[3] = {_mm256_setr_ps(cr, cg, cb, cr, cg, cb, cr, cg),
                             _mm256_setr_ps(cb, cr, cg, cb, cr, cg, cb, cr),
                             _mm256_setr_ps(cg, cb, cr, cg, cb, cr, cg, cb)};
      const __m256 w0 = _mm256_set1_ps(r.b0), w1 = _mm256_set1_ps(r.b1), w2 = _mm256_set1_ps(r.b2);
      const auto* t0 = reinterpret_cast<const __m128i*>(b.half.row(r.corners->v[0]));
      const auto* t1 = reinterpret_cast<const __m128i*>(b.half.row(r.corners->v[1]));
      const auto* t2 = reinterpret_cast<const __m128i*>(b.half.row(r.corners->v[2]));
      for (int k = 0; k < K; ++k) {
        __m256 s = _mm256_mul_ps(_mm256_cvtph_ps(_mm_load_si128(t0 + k)), w0);
        s = _mm256_add_ps(s, _mm256_mul_ps(_mm256_cvtph_ps(_mm_load_si128(t1 + k)), w1));
        s = _mm256_add_ps(s, _mm256_mul_ps(_mm256_cvtph_ps(_mm_load_si128(t2 + k)), w2));
        acc[k] = _mm256_add_ps(acc[k], _mm256_mul_ps(s, rho[k % 3]));
      }
    }
    for (int k = 0; k < K; ++k) _mm256_store_ps(sum + 8 * k, acc[k]);
    float* out = &b.order[v * size_t(b.n2)].x;
    for (int i = 0; i < lanes; ++i) out[i] = sum[i] * w;
  }
}

ChunkOutcome gatherChunk(SurfaceBake& b, const AlbedoLookup& albedo, const Chunk& c) {
  if (activeKernels() == Kernels::Portable) {
    gatherChunkPortable(b, albedo, c);
    return {true, 0};
  }
  switch (b.half.stride / 8) {  // 3·n2 lanes padded to whole cache lines: 4 vectors a line
    case 4:
      gatherChunkF16c<4>(b, albedo, c);
      break;
    case 8:
      gatherChunkF16c<8>(b, albedo, c);
      break;
    case 12:
      gatherChunkF16c<12>(b, albedo, c);
      break;
    case 16:
      gatherChunkF16c<16>(b, albedo, c);
      break;
    case 20:
      gatherChunkF16c<20>(b, albedo, c);
      break;
    case 24:
      gatherChunkF16c<24>(b, albedo, c);
      break;
    default:
      PRT_CHECK(false);
  }
  return {true, 0};
}

// ---- Checkpoint records of the surface stages (checkpoint.h).
// Direct chunk: u8 flags (1: its transfer follows, always with this prt; 2: the hit records
// do not), its transfer (one float per coefficient: the pass is colourless, and it is kept to
// the end as the files' direct part), [CSR offsets, hit records: when bounces follow, unless
// flag 2]. The u8 is 0 in checkpoints of prts that dropped the transfer during the bounces
// (refused by fingerprint). Ranks trade the records without hit records (ranks.h): only the
// chunk's own rank gathers over them.
void writeDirectChunk(const SurfaceBake& b, const Chunk& c, ByteWriter& w, bool withHits = true) {
  w.put<uint8_t>(withHits ? 1 : 3);
  w.putArray(&b.direct[c.begin * b.n2], (c.end - c.begin) * b.n2);
  if (b.keepHits && withHits) {
    w.putArray(b.chunkHits[c.index].begin.data(), b.chunkHits[c.index].begin.size());
    w.putArray(b.chunkHits[c.index].hits.data(), b.chunkHits[c.index].hits.size());
  }
}

void readDirectChunk(SurfaceBake& b, const Chunk& c, ByteReader& r) {
  const uint8_t flags = r.get<uint8_t>();
  if ((flags & 1) == 0) r.fail("direct chunk without transfer");
  std::vector<float> v = r.getVector<float>();
  if (v.size() != (c.end - c.begin) * b.n2) r.fail("direct chunk size");
  std::copy(v.begin(), v.end(), b.direct.begin() + ptrdiff_t(c.begin * b.n2));
  // Another rank's chunk (a merged shard's, or a trade): its hits stay with its own rank. An
  // MPI rank's checkpoint holds only the chunks it computed, whichever they were (ranks.h); a
  // shard reads the merged shards' chunks too, and keeps those of its static share.
  const bool keep = ranks().exchanges() || ranks().owns(c.index);
  if (b.keepHits && !(flags & 2)) {
    ChunkHits& ch = b.chunkHits[c.index];
    ch.begin = r.getVector<uint32_t>();
    ch.hits = r.getVector<HitRecord>();
    if (ch.begin.size() != c.end - c.begin + 1 || ch.begin.front() != 0 || ch.begin.back() != ch.hits.size())
      r.fail("hit records");
    for (const HitRecord& h : ch.hits)
      if (h.tri >= b.lay.triangles) r.fail("hit records");
    if (!keep) ch = ChunkHits{};
    b.holds[c.index] = keep;
  }
}

template <typename T>
void readTransfer(const SurfaceBake& b, ByteReader& r, std::vector<T>& v) {
  v = r.getVector<T>();
  if (v.size() != b.values && !v.empty()) r.fail("transfer size");
}

// Where a checkpoint left off: 0 = in (or before) the direct pass, 1 + k = in bounce k,
// stageDone = the whole surface stage. Restores what that point needs: the finished surface
// stage's sums; or the direct chunks (their transfer and hit records) and the state the bounce
// starts from.
uint32_t restoreSurface(SurfaceBake& b, Checkpoint* cp, ChunkedStage& direct) {
  if (!cp) return 0;
  // Ranks resume together from the earliest point any of them reached: each rank saved all
  // its chunks of a stage before any went on (ChunkedStage::run), so each can restore it.
  const uint32_t resumeStage = uint32_t(ranks().minimum(std::min(cp->restoredStateStage(), b.stageDone)));
  if (resumeStage == b.stageDone) {
    cp->restoreState(b.stageDone, [&](ByteReader& r) {
      b.hitCount = r.get<uint64_t>();
      readTransfer(b, r, b.total);
      readTransfer(b, r, b.lowerOrder);
      readTransfer(b, r, b.direct);
      if (b.total.size() != b.values || b.direct.size() != b.values) r.fail("transfer size");
    });
    return resumeStage;
  }
  b.direct.resize(b.values);
  direct.restore([&](const Chunk& c, ByteReader& r) { readDirectChunk(b, c, r); });
  if (resumeStage != 0) {
    if (direct.chunksLeft() != 0)
      throw Error(cat(cp->path(),
                      ": corrupt checkpoint (hit records of the direct pass missing); delete it to "
                      "start over"));
    // Each MPI rank's checkpoint holds its own chunks: the others' transfer comes from them.
    direct.exchangeWith([&b](uint64_t c, ByteWriter& w) { writeDirectChunk(b, b.chunk(c), w, false); },
                        [&b](const Chunk& c, ByteReader& r) { readDirectChunk(b, c, r); });
    direct.share();
    cp->restoreState(resumeStage, [&](ByteReader& r) {
      readTransfer(b, r, b.order);
      readTransfer(b, r, b.total);
      if (b.order.size() != b.values || b.total.size() != b.values) r.fail("transfer size");
    });
  }
  b.countHits();
  return resumeStage;
}

// The direct pass: visibility-weighted SH, and the hit records for the bounces. Hands the
// bounces t⁰ as both the running sum and the previous order, and keeps it.
void runDirectPass(SurfaceBake& b, ChunkedStage& stage, const BakeControl& control, BakeStats& stats) {
  b.direct.resize(b.values);
  const size_t left = stage.chunksLeft();
  auto tBuild = Clock::now();
  std::optional<RayScene> own;
  const RayScene* rays = nullptr;
  std::vector<glm::vec3> origins;
  float tnear = 0.0f;
  if (left > 0) {
    rays = control.rays ? &control.rays->get() : &own.emplace(b.scene);
    origins = rayOrigins(b.scene, b.lay, *rays);
    tnear = tnearFor(rays->sceneExtent());
    stats.stages.push_back({"bvh", secondsSince(tBuild), 0});
  }
  if (control.checkMemory) {
    double share = 0.0;
    if (b.keepHits && left == 0 && b.lay.vertices > 0) share = double(b.hitCount) / (double(b.lay.vertices) * b.N);
    if (b.keepHits && left > 0) share = pilotFrontHitShare(b.scene, b.lay, *rays, origins, b.settings, tnear);
    control.checkMemory(share);
  }
  Checkpoint::StageIo io;
  io.chunksOutliveStage = b.keepHits;
  io.writeChunk = [&b](uint64_t c, ByteWriter& w) { writeDirectChunk(b, b.chunk(c), w); };
  stage.exchangeWith([&b](uint64_t c, ByteWriter& w) { writeDirectChunk(b, b.chunk(c), w, false); },
                     [&b](const Chunk& c, ByteReader& r) { readDirectChunk(b, c, r); });
  stage.begin(std::move(io));
  TraceClock inEmbree;
  StageStats run = left > 0 ? stage.run(DirectPass{b, *rays, origins, tnear, inEmbree}) : stage.run({});
  run.traceSeconds = inEmbree.seconds();
  stats.rays = run.rays;
  if (left > 0) stats.stages.push_back(run);
  b.countHits();
  b.total.resize(b.values);
  for (size_t i = 0; i < b.values; ++i) b.total[i] = glm::vec3(b.direct[i]);
  b.order = b.total;
}

// Writes rows 0 .. count−1 of `half` back as floats, as putArray writes count · n2 RGB triples.
void writeHalfRows(ByteWriter& w, const HalfRows& half, size_t count, int n2) {
  w.put(uint64_t(count * size_t(n2)));
  constexpr size_t kRows = 1024;
  std::vector<glm::vec3> rows(kRows * size_t(n2));
  for (size_t first = 0; first < count; first += kRows) {
    const size_t n = std::min(kRows, count - first);
    for (size_t v = 0; v < n; ++v)
      for (int i = 0; i < 3 * n2; ++i) (&rows[v * size_t(n2)].x)[i] = floatFromHalf(half.row(first + v)[i]);
    w.write(rows.data(), n * size_t(n2) * sizeof(glm::vec3));
  }
}

// The bounces from `resumeStage` on: t^k = W t^{k−1}, summed into the total. Bounce k's state
// (for a resume) is t^{k−1} as its halves hold it, since the gather overwrites the floats and
// reads nothing else of them: a resume from it gathers the same bits.
void runBounces(SurfaceBake& b, uint32_t resumeStage, Checkpoint* cp, BakeStats& stats) {
  AlbedoLookup albedo(b.scene);
  b.corners = triCorners(b.lay);
  const int n2 = b.n2;
  for (int k = int(resumeStage) - 1; k <= b.bounces; ++k) {
    b.half.assign(b.order, b.lay.vertices, n2);
    StageSpec spec = b.spec(uint32_t(1 + k), cat("bounce ", k), cat("bounce ", k));
    spec.computes = &b.holds;  // where the hit records are
    Checkpoint::StageIo io;
    io.writeState = [&b, n2](ByteWriter& w) {
      writeHalfRows(w, b.half, b.lay.vertices, n2);
      w.putArray(b.total.data(), b.total.size());
    };
    io.writeChunk = [&b, n2](uint64_t c, ByteWriter& w) {
      const Chunk ch = b.chunk(c);
      w.putArray(&b.order[ch.begin * n2], (ch.end - ch.begin) * n2);
    };
    auto restore = [&](const Chunk& c, ByteReader& r) { r.getArray(&b.order[c.begin * n2], (c.end - c.begin) * n2); };
    stats.stages.push_back(
        runChunkedStage(spec, cp, restore, std::move(io), [&](const Chunk& c) { return gatherChunk(b, albedo, c); }));
    if (k == b.bounces && b.settings.keepLowerOrder) b.lowerOrder = b.total;
    for (size_t i = 0; i < b.total.size(); ++i) b.total[i] += b.order[i];
  }
}

// A probe bake follows: keep the finished surface stage, so that resuming an interrupted
// probe stage does not redo it.
void keepSurfaceStage(SurfaceBake& b, Checkpoint& cp) {
  cp.releaseStages();
  Checkpoint::StageIo io;
  io.writeState = [&b](ByteWriter& w) {
    w.put(b.hitCount);
    w.putArray(b.total.data(), b.total.size());
    w.putArray(b.lowerOrder.data(), b.lowerOrder.size());
    w.putArray(b.direct.data(), b.direct.size());
  };
  cp.beginStage(b.stageDone, "surface stage", 0, 0, std::move(io));
  cp.save();
}

// Per Scene::meshes entry: its vertices' part of a buffer in layout order, followed by its
// virtual vertices' part (the back side) when it is double-sided.
template <typename T>
std::vector<std::vector<T>> perMesh(const Scene& scene, const Layout& lay, int n2, const std::vector<T>& all) {
  std::vector<std::vector<T>> out(scene.meshes.size());
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    if (lay.vertexOffset[k] == SIZE_MAX) continue;
    const ptrdiff_t count = ptrdiff_t(scene.meshes[k].vertexCount() * n2);
    auto first = all.begin() + ptrdiff_t(lay.vertexOffset[k] * n2);
    out[k].assign(first, first + count);
    if (lay.backVertexOffset[k] == SIZE_MAX) continue;
    auto back = all.begin() + ptrdiff_t(lay.backVertexOffset[k] * n2);
    out[k].insert(out[k].end(), back, back + count);
  }
  return out;
}

}  // namespace

void validateBands(int bands) {
  if (bands < 1 || bands > sh::kMaxBands) throw Error(cat("bands ", bands, ": must be between 1 and ", sh::kMaxBands));
}

void validate(const BakeSettings& s) {
  validateBands(s.bands);
  if (s.samples < 1 || s.samples > kMaxSamples)
    throw Error(cat("samples ", s.samples, ": must be between 1 and ", kMaxSamples));
  if (s.bounces < 0 || s.bounces > kMaxBounces)
    throw Error(cat("bounces ", s.bounces, ": must be between 0 and ", kMaxBounces));
  if (s.threads < 0) throw Error(cat("threads ", s.threads, ": must be 0 (all cores) or more"));
  if (s.keepGatherRays < 0) throw Error(cat("kept gather rays ", s.keepGatherRays, ": must be 0 (none) or more"));
}

// The first gatherRays rays of each vertex side, moved out of the chunks' hit records: each
// chunk's records are cut, in place, to those of its sides' first rays (the records of a side
// are in ray order, so they lead its own), and its vectors move into the result.
GatherRecords keptGatherRays(SurfaceBake& b) {
  GatherRecords g;
  g.rays = b.gatherRays, g.words = b.gatherWords, g.chunk = kChunk;
  g.chunks.resize(b.chunkHits.size());
  for (size_t c = 0; c < b.chunkHits.size(); ++c) {
    ChunkHits& ch = b.chunkHits[c];
    if (!b.holds[c] || ch.gatherBits.empty()) continue;
    const size_t sides = ch.begin.size() - 1;
    uint32_t kept = 0;
    for (size_t i = 0; i < sides; ++i) {
      const uint64_t* recorded = &ch.gatherBits[i * 2 * g.words + g.words];
      uint32_t n = 0;
      for (uint32_t w = 0; w < g.words; ++w) n += uint32_t(std::popcount(recorded[w]));
      if (kept != ch.begin[i]) std::copy_n(ch.hits.begin() + ch.begin[i], n, ch.hits.begin() + kept);
      ch.begin[i] = kept;
      kept += n;
    }
    ch.begin[sides] = kept;
    ch.hits.resize(kept);
    ch.hits.shrink_to_fit();
    GatherRecords::Chunk& to = g.chunks[c];
    to.bits = std::move(ch.gatherBits), to.begin = std::move(ch.begin), to.hits = std::move(ch.hits);
  }
  return g;
}

// Checkpointing (checkpoint.h): the direct pass saves per chunk its transfer and hit records;
// bounce k saves, once, the state it starts from (t^{k-1} and the running sum) and then per
// chunk its t^k; the finished surface stage saves the sum (and the lower-order sum) for a
// probe bake that follows. Restored values are the very floats an uninterrupted bake holds at
// that point, and every later sum runs in the same order, so the result has the same bits.
SurfaceTransfer bakeSurface(const Scene& scene, const BakeSettings& settings, const BakeControl& control) {
  validate(settings);
  const auto tStart = Clock::now();
  const ThreadLimit threadLimit(settings.threads);
  SurfaceTransfer out;
  out.bands = settings.bands;
  out.perMesh.resize(scene.meshes.size());
  const Layout lay = makeLayout(scene);
  out.stats.vertices = lay.frontVertices;
  out.stats.backVertices = lay.vertices - lay.frontVertices;
  if (!settings.shadowed) {
    auto t0 = Clock::now();
    out.perMeshDirect.resize(scene.meshes.size());
    for (size_t k = 0; k < scene.meshes.size(); ++k) {
      if (scene.meshes[k].receiverOnly) continue;
      out.perMesh[k] = unshadowedTransfer(scene.meshes[k], settings.bands, bakesBackSide(scene, scene.meshes[k]));
      for (const glm::vec3& t : out.perMesh[k]) out.perMeshDirect[k].push_back(t.r);  // all of it is direct
    }
    out.stats.stages.push_back({"unshadowed", secondsSince(t0), 0});
    out.stats.seconds = secondsSince(tStart);
    return out;
  }

  Checkpoint* cp = control.checkpoint;
  const StageRelease release(cp);  // the stages' writers point into `b`
  SurfaceBake b(scene, settings, lay);
  ChunkedStage direct(b.spec(kSurfaceStageDirect, "direct pass", "direct"), cp);
  uint32_t resumeStage = restoreSurface(b, cp, direct);
  out.stats.resumed = cp && cp->exists();
  const bool restoredDone = resumeStage == b.stageDone;
  if (resumeStage == 0) {
    runDirectPass(b, direct, control, out.stats);
    resumeStage = 2;  // bounce 1 starts from the direct pass
  } else if (control.checkMemory) {
    control.checkMemory(b.keepHits ? double(b.hitCount) / (double(lay.vertices) * b.N) : 0.0);
  }
  out.stats.hitRecords = ranks().sum(b.hitCount);  // each rank holds its own chunks' records
  if (resumeStage < b.stageDone) runBounces(b, resumeStage, cp, out.stats);
  // Free what the bounces needed before the per-instance copies below.
  std::vector<glm::vec3>().swap(b.order);
  if (b.gatherWords) out.gather = keptGatherRays(b);
  std::vector<ChunkHits>().swap(b.chunkHits);
  b.half = HalfRows{};
  std::vector<TriCorners>().swap(b.corners);
  if (cp && settings.keepLowerOrder && !restoredDone) keepSurfaceStage(b, *cp);

  out.perMesh = perMesh(scene, lay, b.n2, b.total);
  out.perMeshDirect = perMesh(scene, lay, b.n2, b.direct);
  if (!b.lowerOrder.empty()) out.perMeshLowerOrder = perMesh(scene, lay, b.n2, b.lowerOrder);
  out.stats.seconds = secondsSince(tStart);
  return out;
}

std::vector<Ray> surfaceBakeRays(const Scene& scene, const BakeSettings& settings, const RayScene& rays,
                                 const std::vector<size_t>& vertices) {
  Layout lay = makeLayout(scene);
  std::vector<glm::vec3> origins = rayOrigins(scene, lay, rays);
  const float extent = rays.sceneExtent();
  std::vector<Ray> out(vertices.size() * size_t(settings.samples));
  tbb::parallel_for(size_t(0), vertices.size(), [&](size_t k) {
    const size_t v = vertices[k];
    PRT_CHECK_LT(v, lay.vertices);
    const VertexSampler sampler(origins[v], normalOf(scene, lay, v), settings.seed, v, tnearFor(extent));
    for (uint32_t j = 0; j < uint32_t(settings.samples); ++j) sampler.make(j, out[k * settings.samples + j]);
  });
  return out;
}

namespace {
// Front vertices, then their back sides when the instance's back side is baked.
template <typename T>
void splitSides(const Scene& scene, const MeshInstance& m, std::vector<T>& t, std::vector<T>& front,
                std::vector<T>& back) {
  back.clear();
  if (bakesBackSide(scene, m) && !t.empty()) {
    const auto half = t.begin() + ptrdiff_t(t.size() / 2);
    back.assign(half, t.end());
    t.erase(half, t.end());
  }
  front = std::move(t);
}
}  // namespace

void storeTransfer(Scene& scene, std::vector<std::vector<glm::vec3>> perMesh,
                   std::vector<std::vector<float>> perMeshDirect) {
  PRT_CHECK_EQ(perMesh.size(), scene.meshes.size());
  if (perMeshDirect.empty()) perMeshDirect.resize(scene.meshes.size());
  PRT_CHECK_EQ(perMeshDirect.size(), scene.meshes.size());
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    MeshInstance& m = scene.meshes[k];
    splitSides(scene, m, perMesh[k], m.transfer, m.transferBack);
    splitSides(scene, m, perMeshDirect[k], m.transferDirect, m.transferDirectBack);
  }
}

BakeRecord bakeRecord(const BakeSettings& s, const std::string& sceneName, const std::string& prtVersion) {
  BakeRecord r;
  r.scene = sceneName;
  r.bands = s.bands;
  r.samples = s.samples;
  r.bounces = s.shadowed ? s.bounces : 0;  // an unshadowed bake casts no rays, so no bounce
  r.shadowed = s.shadowed;
  r.seed = s.seed;
  r.prtVersion = prtVersion;
  return r;
}

}  // namespace prt::bake
