// Direct lights' interreflected light, gathered over the bake's own rays (prt/bake/direct_light.h).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <tuple>

#include <tbb/parallel_for.h>

#include "prt/bake/direct_light.h"
#include "prt/bake/ray_scene.h"
#include "prt/error.h"
#include "prt/light.h"
#include "prt/math.h"
#include "prt/sh.h"
#include "sky_prefilter.h"
#include "stage_runner.h"
#include "surface_layout.h"
#include "vertex_rays.h"

namespace prt::bake {

void validate(const BounceSettings& s) {
  if (s.samples < 1 || s.samples > 16777216)
    throw Error(cat("bounce samples ", s.samples, ": must be between 1 and 16777216"));
  if (s.bounces < 0 || s.bounces > 64) throw Error(cat("bounces ", s.bounces, ": must be between 0 and 64"));
  if (s.threads < 0) throw Error(cat("threads ", s.threads, ": must be 0 (all cores) or more"));
}

namespace {

constexpr size_t kChunk = 64;  // vertices per task and per block of hit records

}  // namespace

struct DirectBounce::Impl {
  const Scene& scene;
  BounceSettings settings;
  Layout lay;
  AlbedoLookup albedo;
  std::vector<ChunkHits> chunks;  // chunk c: vertices [c·kChunk, (c+1)·kChunk)
  // Per chunk, per vertex, which of its K rays escaped: ceil(K / 64) words a vertex, bit j of
  // word j / 64 for ray j.
  std::vector<std::vector<uint64_t>> escaped;
  std::vector<glm::vec3> origins;
  float tnear = 0.0f;
  PrefilteredSky filtered;  // the maps skyDetail reads
  uint64_t rays = 0, hits = 0;
  double seconds = 0.0;

  Impl(const Scene& s, const BounceSettings& b)
      : scene(s), settings(b), lay(makeLayout(s)), albedo(s), filtered(uint32_t(b.samples)) {}
};

DirectBounce::DirectBounce(const Scene& scene, const BounceSettings& settings)
    : impl_(std::make_unique<Impl>(scene, settings)) {
  validate(settings);
  const auto t0 = std::chrono::steady_clock::now();
  const ThreadLimit threadLimit(settings.threads);
  Impl& b = *impl_;
  const Layout& lay = b.lay;
  b.chunks.resize((lay.vertices + kChunk - 1) / kChunk);
  b.escaped.resize(b.chunks.size());
  if (lay.vertices == 0) return;
  const RayScene rays(scene);
  const float extent = rays.sceneExtent();
  b.tnear = tnearFor(extent);
  b.origins = rayOrigins(scene, lay, rays);
  const uint32_t K = uint32_t(settings.samples);
  const size_t words = (K + 63) / 64;
  tbb::parallel_for(size_t(0), b.chunks.size(), [&](size_t c) {
    ChunkHits& ch = b.chunks[c];
    ch.begin.assign(1, 0);
    const size_t end = std::min(lay.vertices, (c + 1) * kChunk);
    std::vector<uint64_t>& esc = b.escaped[c];
    esc.assign((end - c * kChunk) * words, 0);
    for (size_t v = c * kChunk; v < end; ++v) {
      const VertexSampler sampler(b.origins[v], normalOf(scene, lay, v), settings.seed, v, b.tnear);
      uint64_t* mask = &esc[(v - c * kChunk) * words];
      traceGatherRays(
          rays, lay, sampler, K, [&](uint32_t j, const Ray&) { mask[j / 64] |= uint64_t(1) << (j % 64); },
          [&](uint32_t tri, uint16_t b1, uint16_t b2) {
            if (settings.bounces > 0) ch.hits.push_back({tri, b1, b2});
          });
      ch.begin.push_back(uint32_t(ch.hits.size()));
    }
    ch.hits.shrink_to_fit();
  });
  b.rays = uint64_t(lay.vertices) * K;
  for (const ChunkHits& ch : b.chunks) b.hits += ch.hits.size();
  b.seconds = secondsSince(t0);
}

DirectBounce::~DirectBounce() = default;

uint64_t DirectBounce::rays() const { return impl_->rays; }
uint64_t DirectBounce::hitRecords() const { return impl_->hits; }
double DirectBounce::traceSeconds() const { return impl_->seconds; }

void addIrradiance(DirectIrradiance& a, const DirectIrradiance& b) {
  for (size_t k = 0; k < b.front.size() && k < a.front.size(); ++k) {
    for (size_t v = 0; v < b.front[k].size() && v < a.front[k].size(); ++v) a.front[k][v] += b.front[k][v];
    for (size_t v = 0; v < b.back[k].size() && v < a.back[k].size(); ++v) a.back[k][v] += b.back[k][v];
  }
}

DirectIrradiance DirectBounce::skyDetail(const RigBackground& skyIn, const sh::ShRgb& sh) const {
  const auto t0 = std::chrono::steady_clock::now();
  const ThreadLimit threadLimit(impl_->settings.threads);
  const Impl& b = *impl_;
  const Layout& lay = b.lay;
  const Scene& scene = b.scene;
  const int bands = scene.transferBands > 0 ? scene.transferBands : sh.bands;
  const int n2 = bands * bands;
  const uint32_t K = uint32_t(b.settings.samples);
  const size_t words = (K + 63) / 64;
  std::vector<glm::vec3> delta(lay.vertices, glm::vec3(0.0f));
  const RigBackground sky = b.filtered(skyIn);
  tbb::parallel_for(size_t(0), b.chunks.size(), [&](size_t c) {
    const size_t first = c * kChunk, end = std::min(lay.vertices, first + kChunk);
    double y[sh::kMaxBands * sh::kMaxBands];
    Ray ray;
    for (size_t v = first; v < end; ++v) {
      const VertexSampler sampler(b.origins[v], normalOf(scene, lay, v), b.settings.seed, v, b.tnear);
      const uint64_t* mask = &b.escaped[c][(v - first) * words];
      glm::dvec3 sum(0.0);
      for (uint32_t j = 0; j < K; ++j) {
        if (!(mask[j / 64] >> (j % 64) & 1)) continue;
        sampler.make(j, ray);
        const glm::dvec3 d(ray.dir);
        sh::evaluate(bands, d, y);
        glm::dvec3 band(0.0);
        for (int i = 0; i < n2 && i < int(sh.c.size()); ++i) band += y[i] * glm::dvec3(sh.c[size_t(i)]);
        sum += sky.radiance(d) - band;
      }
      delta[v] = glm::vec3(sum * (kPiF / double(K)));
    }
  });
  DirectIrradiance out = perInstance(scene, lay, delta);
  out.seconds = secondsSince(t0);
  return out;
}

DirectIrradiance DirectBounce::bounce(const DirectIrradiance& e0) const {
  const auto t0 = std::chrono::steady_clock::now();
  const ThreadLimit threadLimit(impl_->settings.threads);
  const Impl& b = *impl_;
  const Layout& lay = b.lay;
  const Scene& scene = b.scene;
  // E⁰ in the layout's numbering; a side without values is dark.
  std::vector<glm::vec3> prev = sideValues(scene, lay, e0), cur(lay.vertices), sum(lay.vertices, glm::vec3(0.0f));
  const float w = 1.0f / float(b.settings.samples);
  for (int bounce = 0; bounce < b.settings.bounces; ++bounce) {
    tbb::parallel_for(size_t(0), b.chunks.size(), [&](size_t c) {
      const ChunkHits& ch = b.chunks[c];
      const size_t first = c * kChunk;
      thread_local VaryingColours colours;
      for (size_t v = first; v + 1 - first < ch.begin.size(); ++v) {
        glm::vec3 acc(0.0f);
        const uint32_t begin = ch.begin[v - first], end = ch.begin[v - first + 1];
        if (b.albedo.varies) colours.start(b.albedo, lay, ch.hits.data(), begin, end);
        for (uint32_t h = begin; h < end; ++h) {
          const HitRecord& rec = ch.hits[h];
          const float b1 = rec.b1 * (1.0f / 65535.0f), b2 = rec.b2 * (1.0f / 65535.0f), b0 = 1.0f - b1 - b2;
          const uint32_t* tv = &lay.triVerts[3 * size_t(rec.tri)];
          const uint32_t mesh = lay.meshOfTri[rec.tri];
          const glm::vec3 rho = b.albedo.uniform[mesh] ? b.albedo.constant[mesh] : colours.next();
          acc += rho * (b0 * prev[tv[0]] + b1 * prev[tv[1]] + b2 * prev[tv[2]]);
        }
        cur[v] = acc * w;
        sum[v] += cur[v];
      }
    });
    std::swap(prev, cur);
  }
  DirectIrradiance out = perInstance(scene, lay, sum, &e0);
  out.seconds = secondsSince(t0);
  return out;
}

}  // namespace prt::bake
