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
// matrix-vector product, no new rays. Back-face hits block light and send none (the back of a
// one-sided surface has no transfer).
#include "prt/bake/surface_bake.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "albedo_lookup.h"
#include "prt/bake/ray_scene.h"
#include "prt/bake/sampling.h"
#include "prt/error.h"
#include "prt/progress.h"
#include "prt/sh.h"

namespace prt::bake {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Rays per Embree stream: enough to amortise the call, small enough to stay in cache.
constexpr int kStream = 256;
// Vertices per task: the unit of parallel work and of hit-record storage.
constexpr size_t kChunk = 64;

// Global numbering of the baked (non-receiver) instances' vertices and triangles.
struct Layout {
  std::vector<size_t> vertexOffset;  // per Scene::meshes entry (SIZE_MAX for receivers)
  std::vector<uint32_t> triOffset;   // per mesh, global index of its first triangle
  std::vector<uint32_t> meshOfVertex;
  std::vector<uint32_t> triVerts;    // global triangle -> 3 global vertex indices
  std::vector<uint32_t> meshOfTri;
  size_t vertices = 0;
  size_t triangles = 0;
};

Layout makeLayout(const Scene& scene) {
  Layout lay;
  lay.vertexOffset.assign(scene.meshes.size(), SIZE_MAX);
  lay.triOffset.assign(scene.meshes.size(), 0);
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    lay.triOffset[k] = static_cast<uint32_t>(lay.triangles);
    if (m.receiverOnly) continue;
    lay.vertexOffset[k] = lay.vertices;
    lay.vertices += m.vertexCount();
    lay.triangles += m.triangleCount();
  }
  if (lay.triangles >= std::numeric_limits<uint32_t>::max() ||
      lay.vertices >= std::numeric_limits<uint32_t>::max())
    throw Error(cat("scene too large: ", lay.triangles, " triangles, ", lay.vertices,
                    " vertices (at most 2^32 - 1 each)"));
  lay.meshOfVertex.resize(lay.vertices);
  lay.triVerts.resize(lay.triangles * 3);
  lay.meshOfTri.resize(lay.triangles);
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if (m.receiverOnly) continue;
    size_t v0 = lay.vertexOffset[k];
    std::fill_n(lay.meshOfVertex.begin() + v0, m.vertexCount(), uint32_t(k));
    for (size_t t = 0; t < m.triangleCount(); ++t) {
      size_t g = lay.triOffset[k] + t;
      lay.meshOfTri[g] = uint32_t(k);
      for (int c = 0; c < 3; ++c) lay.triVerts[3 * g + c] = uint32_t(v0 + m.indices[3 * t + c]);
    }
  }
  return lay;
}

// Where rays of each vertex start. A vertex lies on its own triangles and, at a corner of a
// room, on the plane of the next wall too: a ray leaving exactly there can slip through that
// wall and see the sky. The origin is therefore lifted along the normal *and* pulled towards
// the centroids of the vertex's triangles, by a small fraction of the scene size.
std::vector<glm::vec3> rayOrigins(const Scene& scene, const Layout& lay, float extent) {
  std::vector<glm::vec3> pull(lay.vertices, glm::vec3(0.0f));
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if (m.receiverOnly) continue;
    size_t v0 = lay.vertexOffset[k];
    for (size_t t = 0; t < m.triangleCount(); ++t) {
      const uint32_t* ix = &m.indices[3 * t];
      glm::vec3 c = (m.positions[ix[0]] + m.positions[ix[1]] + m.positions[ix[2]]) / 3.0f;
      for (int j = 0; j < 3; ++j) {
        glm::vec3 d = c - m.positions[ix[j]];
        float len = glm::length(d);
        if (len > 0.0f) pull[v0 + ix[j]] += d / len;
      }
    }
  }
  const float eps = 1e-4f * extent;
  std::vector<glm::vec3> origins(lay.vertices);
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if (m.receiverOnly) continue;
    size_t v0 = lay.vertexOffset[k];
    for (size_t i = 0; i < m.vertexCount(); ++i) {
      glm::vec3 p = pull[v0 + i];
      float len = glm::length(p);
      if (len > 0.0f) p /= len;
      origins[v0 + i] = m.positions[i] + eps * (m.normals[i] + p);
    }
  }
  return origins;
}

// A front-face hit kept for the bounces: 8 bytes.
struct HitRecord {
  uint32_t tri;     // global triangle
  uint16_t b1, b2;  // barycentrics of its 2nd and 3rd vertex, 16-bit fixed point
};

inline uint16_t quantise(float b) {
  return static_cast<uint16_t>(std::lround(std::clamp(b, 0.0f, 1.0f) * 65535.0f));
}

// Hit records of one chunk of vertices, CSR: hits of vertex v are [begin[v], begin[v+1]).
struct ChunkHits {
  std::vector<HitRecord> hits;
  std::vector<uint32_t> begin;
};

std::vector<glm::vec3> unshadowedTransfer(const MeshInstance& m, int bands) {
  const int n2 = bands * bands;
  std::vector<glm::vec3> t(m.vertexCount() * n2);
  float y[sh::kMaxBands * sh::kMaxBands];
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    sh::evaluate(bands, m.normals[v], y);
    for (int l = 0; l < bands; ++l) {
      float a = float(sh::clampedCosineFactor(l));
      for (int mm = -l; mm <= l; ++mm) t[v * n2 + sh::index(l, mm)] = glm::vec3(a * y[sh::index(l, mm)]);
    }
  }
  return t;
}

// Ray j of vertex v, exactly as the bake casts it.
struct VertexSampler {
  glm::vec3 origin;
  Frame frame;
  uint32_t s0, s1;
  float tnear;
  VertexSampler(const glm::vec3& org, const glm::vec3& n, uint64_t seed, size_t v, float tn)
      : origin(org), frame(Frame::fromNormal(n)), tnear(tn) {
    const uint64_t h = splitMix64(seed ^ splitMix64(v));
    s0 = uint32_t(h);
    s1 = uint32_t(h >> 32);
  }
  void make(uint32_t j, Ray& ray) const {
    ray = Ray{};
    ray.org = origin;
    ray.tnear = tnear;
    ray.dir = frame.toWorld(sampleCosineHemisphere({sobol0(j, s0), sobol1(j, s1)}));
    ray.tfar = std::numeric_limits<float>::infinity();
  }
};

const glm::vec3& normalOf(const Scene& scene, const Layout& lay, size_t v) {
  uint32_t k = lay.meshOfVertex[v];
  return scene.meshes[k].normals[v - lay.vertexOffset[k]];
}

float tnearFor(float extent) { return 1e-6f * extent; }

// An upper bound on the share of direct rays that hit a front face, from a pilot: the first
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
    for (uint32_t j = 0; j < p; ++j) front += batch[j].hit() && !batch[j].backface();
    share[i] = double(front) / p;
  });
  double mean = 0, var = 0;
  for (double s : share) mean += s;
  mean /= double(m);
  for (double s : share) var += (s - mean) * (s - mean);
  var /= double(std::max<size_t>(m - 1, 1));
  return std::min(1.0, mean + 3.0 * std::sqrt(var / double(m)) + 0.02);
}

}  // namespace

void validate(const BakeSettings& s) {
  if (s.bands < 1 || s.bands > sh::kMaxBands)
    throw Error(cat("--bands ", s.bands, ": must be between 1 and ", sh::kMaxBands));
  if (s.samples < 1 || s.samples > (1 << 24))
    throw Error(cat("--samples ", s.samples, ": must be between 1 and ", 1 << 24));
  if (s.bounces < 0 || s.bounces > 64) throw Error(cat("--bounces ", s.bounces, ": must be between 0 and 64"));
  if (s.threads < 0) throw Error(cat("--threads ", s.threads, ": must be 0 (all cores) or more"));
}

// Checkpointing (checkpoint.h): the direct pass saves per chunk its transfer and hit records;
// bounce k saves, once, the state it starts from (t^{k-1} and the running sum) and then per
// chunk its t^k; the finished surface stage saves the sum (and the lower-order sum) for a
// probe bake that follows. Restored values are the very floats an uninterrupted bake holds at
// that point, and every later sum runs in the same order, so the result has the same bits.
SurfaceTransfer bakeSurface(const Scene& scene, const BakeSettings& settings, const BakeControl& control) {
  validate(settings);
  const auto tStart = Clock::now();
  std::unique_ptr<tbb::global_control> threadLimit;
  if (settings.threads > 0)
    threadLimit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                        size_t(settings.threads));
  const int bands = settings.bands;
  const int n2 = bands * bands;

  SurfaceTransfer out;
  out.bands = bands;
  out.perMesh.resize(scene.meshes.size());
  Layout lay = makeLayout(scene);
  out.stats.vertices = lay.vertices;

  if (!settings.shadowed) {
    auto t0 = Clock::now();
    for (size_t k = 0; k < scene.meshes.size(); ++k)
      if (!scene.meshes[k].receiverOnly) out.perMesh[k] = unshadowedTransfer(scene.meshes[k], bands);
    out.stats.stages.push_back({"unshadowed", secondsSince(t0), 0});
    out.stats.seconds = secondsSince(tStart);
    return out;
  }

  Checkpoint* cp = control.checkpoint;
  // The stages' writers point into this function's buffers: forget them however it ends.
  struct Release {
    Checkpoint* cp;
    ~Release() {
      if (cp) cp->releaseStages();
    }
  } release{cp};
  auto stopIfInterrupted = [&] {
    if (cp) cp->stopIfInterrupted();
    if (interruptRequested()) throw Interrupted("interrupted");
  };

  const bool keepHits = settings.bounces > 0;
  const int bounces = keepHits ? settings.bounces : 0;
  const uint32_t stageDone = uint32_t(2 + bounces);
  const uint32_t N = uint32_t(settings.samples);
  const size_t chunks = (lay.vertices + kChunk - 1) / kChunk;
  const size_t values = lay.vertices * n2;
  auto chunkRange = [&](size_t c) { return std::pair(c * kChunk, std::min(lay.vertices, (c + 1) * kChunk)); };
  std::vector<ChunkHits> chunkHits(keepHits ? chunks : 0);
  std::vector<uint8_t> chunkDone(chunks, 0);
  std::vector<glm::vec3> direct, total, lowerOrder, prev, cur;
  auto readVec3 = [&](ByteReader& r, std::vector<glm::vec3>& v) {
    v = r.getVector<glm::vec3>();
    if (v.size() != values && !v.empty()) r.fail("transfer size");
  };

  // ---- Where a checkpoint left off: 0 = in (or before) the direct pass, 1 + k = in bounce k,
  // stageDone = the whole surface stage.
  uint32_t resumeStage = 0;
  uint64_t hitCount = 0;
  if (cp) {
    resumeStage = std::min(cp->restoredStateStage(), stageDone);
    out.stats.resumed = cp->exists();
  }
  const bool restoredDone = resumeStage == stageDone;
  if (restoredDone) {
    cp->restoreState(stageDone, [&](ByteReader& r) {
      hitCount = r.get<uint64_t>();
      readVec3(r, total);
      readVec3(r, lowerOrder);
      if (total.size() != values) r.fail("transfer size");
    });
  } else if (cp) {
    const bool wantValues = resumeStage == 0;
    if (wantValues) direct.resize(values);
    cp->restoreChunks(kSurfaceStageDirect, [&](uint64_t c, ByteReader& r) {
      if (c >= chunks) r.fail("chunk index");
      auto [vBegin, vEnd] = chunkRange(c);
      const bool hasValues = r.get<uint8_t>() != 0;
      if (wantValues && !hasValues) r.fail("direct chunk without transfer");
      std::vector<float> v = hasValues ? r.getVector<float>() : std::vector<float>();
      if (hasValues && v.size() != (vEnd - vBegin) * n2) r.fail("direct chunk size");
      if (wantValues)
        for (size_t i = 0; i < v.size(); ++i) direct[vBegin * n2 + i] = glm::vec3(v[i]);
      if (keepHits) {
        ChunkHits& ch = chunkHits[c];
        ch.begin = r.getVector<uint32_t>();
        ch.hits = r.getVector<HitRecord>();
        if (ch.begin.size() != vEnd - vBegin + 1 || ch.begin.front() != 0 || ch.begin.back() != ch.hits.size())
          r.fail("hit records");
        for (const HitRecord& h : ch.hits)
          if (h.tri >= lay.triangles) r.fail("hit records");
      }
      chunkDone[c] = 1;
    });
    if (resumeStage != 0) {
      if (std::count(chunkDone.begin(), chunkDone.end(), 1) != ptrdiff_t(chunks))
        throw Error(cat(cp->path(), ": corrupt checkpoint (hit records of the direct pass missing); delete it to "
                                    "start over"));
      cp->restoreState(resumeStage, [&](ByteReader& r) {
        readVec3(r, prev);
        readVec3(r, total);
        if (prev.size() != values || total.size() != values) r.fail("transfer size");
      });
    }
  }
  for (const ChunkHits& ch : chunkHits) hitCount += ch.hits.size();
  const size_t directLeft = chunks - size_t(std::count(chunkDone.begin(), chunkDone.end(), 1));

  // Direct chunk records carry their transfer while it exists. Outside the block below: with
  // hit records kept, checkpoints saved during the bounces still write the direct chunks.
  bool directAlive = true;
  if (resumeStage == 0) {
    direct.resize(values);
    // ---- Direct pass: visibility-weighted SH, and the hit records for the bounces.
    auto tBuild = Clock::now();
    std::optional<RayScene> rays;
    std::vector<glm::vec3> origins;
    float tnear = 0.0f;
    if (directLeft > 0) {
      rays.emplace(scene);
      origins = rayOrigins(scene, lay, rays->sceneExtent());
      tnear = tnearFor(rays->sceneExtent());
      out.stats.stages.push_back({"bvh", secondsSince(tBuild), 0});
    }
    if (control.checkMemory) {
      double share = 0.0;
      if (keepHits && directLeft == 0 && lay.vertices > 0) share = double(hitCount) / (double(lay.vertices) * N);
      if (keepHits && directLeft > 0) share = pilotFrontHitShare(scene, lay, *rays, origins, settings, tnear);
      control.checkMemory(share);
    }
    if (cp) {
      Checkpoint::StageIo io;
      io.chunksOutliveStage = keepHits;
      io.writeChunk = [&](uint64_t c, ByteWriter& w) {
        auto [vBegin, vEnd] = chunkRange(c);
        w.put<uint8_t>(directAlive);
        if (directAlive) {
          std::vector<float> v((vEnd - vBegin) * n2);
          for (size_t i = 0; i < v.size(); ++i) v[i] = direct[vBegin * n2 + i].r;
          w.putArray(v.data(), v.size());
        }
        if (keepHits) {
          w.putArray(chunkHits[c].begin.data(), chunkHits[c].begin.size());
          w.putArray(chunkHits[c].hits.data(), chunkHits[c].hits.size());
        }
      };
      cp->beginStage(kSurfaceStageDirect, "direct pass", chunks, chunks - directLeft, std::move(io));
    }
    auto tDirect = Clock::now();
    std::atomic<uint64_t> raysCast{0};
    if (directLeft > 0) {
      Progress progress("direct", lay.vertices, "vertices", settings.progress);
      progress.add((chunks - directLeft) * kChunk);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, chunks, 1), [&](const tbb::blocked_range<size_t>& r) {
        alignas(64) Ray batch[kStream];
        double acc[sh::kMaxBands * sh::kMaxBands];
        float y[sh::kMaxBands * sh::kMaxBands];
        for (size_t c = r.begin(); c != r.end(); ++c) {
          if (chunkDone[c] || interruptRequested()) continue;
          auto [vBegin, vEnd] = chunkRange(c);
          ChunkHits* ch = keepHits ? &chunkHits[c] : nullptr;
          if (ch) ch->begin.assign(1, 0);
          bool abandoned = false;
          for (size_t v = vBegin; v < vEnd; ++v) {
            if (interruptRequested()) {  // a chunk can take long at huge --samples
              abandoned = true;
              break;
            }
            const VertexSampler sampler(origins[v], normalOf(scene, lay, v), settings.seed, v, tnear);
            std::fill_n(acc, n2, 0.0);
            for (uint32_t first = 0; first < N; first += kStream) {
              const uint32_t count = std::min<uint32_t>(kStream, N - first);
              for (uint32_t j = 0; j < count; ++j) sampler.make(first + j, batch[j]);
              if (keepHits)
                rays->intersect(batch, count);
              else
                rays->occluded(batch, count);
              for (uint32_t j = 0; j < count; ++j) {
                const Ray& ray = batch[j];
                const bool blocked = keepHits ? ray.hit() : ray.occludedHit();
                if (!blocked) {
                  sh::evaluate(bands, ray.dir, y);
                  for (int i = 0; i < n2; ++i) acc[i] += y[i];
                } else if (keepHits && !ray.backface()) {
                  ch->hits.push_back({lay.triOffset[ray.mesh] + ray.tri, quantise(ray.u), quantise(ray.v)});
                }
              }
            }
            const double w = M_PI / N;
            for (int i = 0; i < n2; ++i) direct[v * n2 + i] = glm::vec3(float(acc[i] * w));
            if (ch) ch->begin.push_back(uint32_t(ch->hits.size()));
          }
          if (abandoned) {
            if (ch) *ch = ChunkHits{};
            continue;
          }
          if (ch) ch->hits.shrink_to_fit();
          chunkDone[c] = 1;
          raysCast += uint64_t(vEnd - vBegin) * N;
          if (cp) cp->complete(c);
          progress.add(vEnd - vBegin);
        }
      });
      progress.finish();
    }
    stopIfInterrupted();
    if (cp) cp->endStage();
    out.stats.rays = raysCast.load();
    if (directLeft > 0) out.stats.stages.push_back({"direct", secondsSince(tDirect), out.stats.rays});
    hitCount = 0;
    for (const ChunkHits& ch : chunkHits) hitCount += ch.hits.size();
    total = direct;
    prev = std::move(direct);
    directAlive = false;
    resumeStage = 2;  // bounce 1 starts from the direct pass
  } else if (control.checkMemory) {
    control.checkMemory(keepHits ? double(hitCount) / (double(lay.vertices) * N) : 0.0);
  }
  out.stats.hitRecords = hitCount;

  // ---- Bounces: t^k = W t^{k-1}, gathered over the hit records.
  if (resumeStage < stageDone) {
    AlbedoLookup albedo(scene);
    cur.resize(values);
    for (int k = int(resumeStage) - 1; k <= bounces; ++k) {
      const uint32_t stage = uint32_t(1 + k);
      auto tBounce = Clock::now();
      std::fill(chunkDone.begin(), chunkDone.end(), 0);
      uint64_t restored = 0;
      if (cp)
        restored = cp->restoreChunks(stage, [&](uint64_t c, ByteReader& r) {
          if (c >= chunks) r.fail("chunk index");
          auto [vBegin, vEnd] = chunkRange(c);
          r.getArray(&cur[vBegin * n2], (vEnd - vBegin) * n2);
          chunkDone[c] = 1;
        });
      if (cp) {
        Checkpoint::StageIo io;
        io.writeState = [&](ByteWriter& w) {
          w.putArray(prev.data(), prev.size());
          w.putArray(total.data(), total.size());
        };
        io.writeChunk = [&](uint64_t c, ByteWriter& w) {
          auto [vBegin, vEnd] = chunkRange(c);
          w.putArray(&cur[vBegin * n2], (vEnd - vBegin) * n2);
        };
        cp->beginStage(stage, cat("bounce ", k), chunks, restored, std::move(io));
      }
      Progress progress(cat("bounce ", k), lay.vertices, "vertices", settings.progress);
      progress.add(restored * kChunk);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, chunks, 1), [&](const tbb::blocked_range<size_t>& r) {
        glm::vec3 acc[sh::kMaxBands * sh::kMaxBands];
        for (size_t c = r.begin(); c != r.end(); ++c) {
          if (chunkDone[c] || interruptRequested()) continue;
          const ChunkHits& ch = chunkHits[c];
          auto [vBegin, vEnd] = chunkRange(c);
          for (size_t v = vBegin; v < vEnd; ++v) {
            std::fill_n(acc, n2, glm::vec3(0.0f));
            for (uint32_t h = ch.begin[v - vBegin]; h < ch.begin[v - vBegin + 1]; ++h) {
              const HitRecord& rec = ch.hits[h];
              const float b1 = rec.b1 * (1.0f / 65535.0f), b2 = rec.b2 * (1.0f / 65535.0f);
              const float b0 = 1.0f - b1 - b2;
              const uint32_t mesh = lay.meshOfTri[rec.tri];
              const glm::vec3 rho = albedo.at(mesh, rec.tri - lay.triOffset[mesh], b1, b2);
              const glm::vec3* t0 = &prev[size_t(lay.triVerts[3 * rec.tri + 0]) * n2];
              const glm::vec3* t1 = &prev[size_t(lay.triVerts[3 * rec.tri + 1]) * n2];
              const glm::vec3* t2 = &prev[size_t(lay.triVerts[3 * rec.tri + 2]) * n2];
              for (int i = 0; i < n2; ++i) acc[i] += rho * (b0 * t0[i] + b1 * t1[i] + b2 * t2[i]);
            }
            const float w = 1.0f / float(N);
            for (int i = 0; i < n2; ++i) cur[v * n2 + i] = acc[i] * w;
          }
          if (cp) cp->complete(c);
          progress.add(vEnd - vBegin);
        }
      });
      progress.finish();
      stopIfInterrupted();
      if (cp) cp->endStage();
      if (k == bounces && settings.keepLowerOrder) lowerOrder = total;
      for (size_t i = 0; i < total.size(); ++i) total[i] += cur[i];
      std::swap(prev, cur);
      out.stats.stages.push_back({cat("bounce ", k), secondsSince(tBounce), 0});
    }
  }
  // Free what the bounces needed before the per-instance copies below.
  std::vector<glm::vec3>().swap(prev);
  std::vector<glm::vec3>().swap(cur);
  std::vector<ChunkHits>().swap(chunkHits);
  // A probe bake follows: keep the finished surface stage, so that resuming an interrupted
  // probe stage does not redo it.
  if (cp && settings.keepLowerOrder && !restoredDone) {
    cp->releaseStages();
    Checkpoint::StageIo io;
    io.writeState = [&](ByteWriter& w) {
      w.put(hitCount);
      w.putArray(total.data(), total.size());
      w.putArray(lowerOrder.data(), lowerOrder.size());
    };
    cp->beginStage(stageDone, "surface stage", 0, 0, std::move(io));
    cp->save();
  }

  auto split = [&](const std::vector<glm::vec3>& all, std::vector<std::vector<glm::vec3>>& perMesh) {
    perMesh.assign(scene.meshes.size(), {});
    for (size_t k = 0; k < scene.meshes.size(); ++k) {
      if (lay.vertexOffset[k] == SIZE_MAX) continue;
      auto first = all.begin() + ptrdiff_t(lay.vertexOffset[k] * n2);
      perMesh[k].assign(first, first + ptrdiff_t(scene.meshes[k].vertexCount() * n2));
    }
  };
  split(total, out.perMesh);
  if (!lowerOrder.empty()) split(lowerOrder, out.perMeshLowerOrder);
  out.stats.seconds = secondsSince(tStart);
  return out;
}

std::vector<Ray> surfaceBakeRays(const Scene& scene, const BakeSettings& settings, float extent,
                                 const std::vector<size_t>& vertices) {
  Layout lay = makeLayout(scene);
  std::vector<glm::vec3> origins = rayOrigins(scene, lay, extent);
  std::vector<Ray> out(vertices.size() * size_t(settings.samples));
  tbb::parallel_for(size_t(0), vertices.size(), [&](size_t k) {
    const size_t v = vertices[k];
    PRT_CHECK_LT(v, lay.vertices);
    const VertexSampler sampler(origins[v], normalOf(scene, lay, v), settings.seed, v, tnearFor(extent));
    for (uint32_t j = 0; j < uint32_t(settings.samples); ++j) sampler.make(j, out[k * settings.samples + j]);
  });
  return out;
}

std::string settingsJson(const BakeSettings& s, const std::string& sceneName) {
  nlohmann::json j;
  j["version"] = 1;
  j["scene"] = sceneName;
  j["bands"] = s.bands;
  j["samples"] = s.samples;
  j["bounces"] = s.shadowed ? s.bounces : 0;
  j["shadowed"] = s.shadowed;
  j["seed"] = s.seed;
  j["transfer"] = "irradiance";
  j["sh_convention"] = "real orthonormal, no Condon-Shortley phase, index l(l+1)+m, glTF axes";
  j["units"] = "E = transfer . light (irradiance); L_o = albedo / pi * E";
  return j.dump();
}

}  // namespace prt::bake
