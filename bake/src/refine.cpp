// Adaptive refinement of the baked meshes (refine.h, docs/bake.md "Refinement").
//
// What is measured. Per point x with normal N the direct pass's estimator (vertex_rays.h, the
// bake's ray origins and cosine-weighted Sobol directions) gives the blocked transfer
//   b_i(x) = t^unocc_i − t⁰_i ≈ (π/n) Σ_s (1 − V_s) y_i(ω_s),
// with per coefficient the sample variance of the mean, s²_i = (π² Σ_s (1−V_s) y_i² / n − b_i²) / n.
// Measuring b rather than t⁰ leaves out the unoccluded part, whose interpolation across a
// triangle is the normals' (the mesh as its author shaded it), and makes an unoccluded point
// exactly zero with zero variance: noise cannot split a surface that sees the whole sky.
// Every point uses the same scramble (common random numbers), so neighbouring points with one
// normal see the same directions and their differences carry little noise.
//
// The error of an edge (a, b) with midpoint m is e = b(m) − (b(a) + b(b))/2, with
// σ² = Σ_i s²_i(m) + (s²_i(a) + s²_i(b))/4 (as if independent: a bound for correlated
// estimates); of a triangle with centroid c, e = b(c) − (b(a) + b(b) + b(c'))/3, σ² = s²(c) +
// Σ s²(corners)/9. The score is (|e| − kNoiseSigmas·σ) / R, R = |t^unocc| = (Σ_l Â_l² (2l+1)/4π)^½
// (the same for every normal): the worst irradiance error over lights of unit norm, relative
// to the best unoccluded irradiance over them. Scores above the tolerance are split, largest
// first, until the budget is spent.
//
// How edges are split: longest-edge bisection with conforming closure (Rivara 1984): marking an
// edge marks the longest edge of every triangle beside it, recursively; then every triangle
// with marked edges is bisected at its longest edge, and its children at their marked edges.
// A marked edge is split in every triangle that has it, at one new vertex per pair of
// indices, so the mesh stays conforming. Edges are matched by their ends' positions, so across
// a UV seam or a flat-normal split (vertices with equal positions and other attributes) both
// sides split alike, at midpoints computed from equal floats: equal positions.
//
// Determinism: every estimate is a function of its point alone; selection and splitting run
// in one thread in mesh order.
#include "prt/bake/refine.h"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <set>
#include <unordered_map>
#include <unordered_set>

#include <tbb/parallel_for.h>

#include "prt/bake/interrupt.h"
#include "prt/bake/ray_scene.h"
#include "prt/error.h"
#include "prt/sh.h"
#include "stage_runner.h"
#include "vertex_rays.h"

namespace prt::bake {

namespace {

using Clock = std::chrono::steady_clock;
using Blend = MeshInstance::FileBlend;

// How many standard errors of Monte Carlo noise an error must exceed before it counts.
constexpr double kNoiseSigmas = 2.0;
// The scramble of every refinement point (common random numbers), a "vertex index" no bake uses
// for anything else.
constexpr size_t kRefineStream = 0x7265666eu;
constexpr int kStream = 256;
// Points (or candidates) an MPI rank takes at a time: a block holds both sides of a two-sided
// instance's points, which sit side by side (split point by point, one rank had every front
// side and the other every back side: on cornell_open one rank took 20% longer).
constexpr size_t kShareBlock = 64;

uint64_t edgeKey(uint32_t a, uint32_t b) { return a < b ? (uint64_t(a) << 32 | b) : (uint64_t(b) << 32 | a); }

// Merges weighted blends: combines equal vertices, keeps non-zero weights (at most three, since
// every point of a refined triangle lies in one original triangle).
Blend mergeBlends(std::initializer_list<std::pair<const Blend*, float>> parts) {
  std::array<uint32_t, 9> v{};
  std::array<float, 9> w{};
  int n = 0;
  for (const auto& [b, scale] : parts)
    for (int j = 0; j < 3; ++j) {
      if (b->weight[j] == 0.0f) continue;
      int k = 0;
      while (k < n && v[size_t(k)] != b->vertex[j]) ++k;
      if (k == n) {
        v[size_t(n)] = b->vertex[j];
        w[size_t(n++)] = 0.0f;
      }
      w[size_t(k)] += scale * b->weight[j];
    }
  PRT_CHECK_LE(n, 3);
  Blend out;
  for (int j = 0; j < 3; ++j) {
    out.vertex[j] = j < n ? v[size_t(j)] : 0;
    out.weight[j] = j < n ? w[size_t(j)] : 0.0f;
  }
  return out;
}

// Where a point's estimate is taken.
struct Point {
  glm::vec3 position, normal, pull;
};

// What the rays of each point found: its normal and, per direction, whether it was blocked.
struct Estimates {
  static constexpr uint32_t kNone = ~uint32_t(0);
  size_t words = 0;  // 64-bit words of blocked bits per point
  std::vector<glm::vec3> normal;
  std::vector<uint64_t> blocked;
  std::vector<uint32_t> back;  // per point: the slot of its back side (double-sided instances), or kNone
  uint32_t add() {
    normal.emplace_back(0.0f);
    blocked.resize(blocked.size() + words, 0);
    back.push_back(kNone);
    return uint32_t(normal.size() - 1);
  }
  bool bit(uint32_t point, uint32_t s) const { return (blocked[point * words + s / 64] >> (s % 64)) & 1u; }
};

struct Estimator {
  const RayScene& rays;
  int bands, n2;
  uint32_t samples;
  uint64_t seed;
  float extent, tnear;
  std::vector<glm::vec3> local;  // direction s about +Z, as VertexSampler makes it for every point
  double reference;              // |t^unocc|

  Estimator(const RayScene& r, int bands_, uint32_t samples_, uint64_t seed_, float extent_)
      : rays(r), bands(bands_), n2(bands_ * bands_), samples(samples_), seed(seed_), extent(extent_),
        tnear(tnearFor(extent_)), local(samples_) {
    const VertexSampler up(glm::vec3(0.0f), glm::vec3(0, 0, 1), seed, kRefineStream, tnear);
    Ray ray;
    for (uint32_t j = 0; j < samples; ++j) {
      up.make(j, ray);
      local[j] = ray.dir;
    }
    reference = 0.0;
    for (int l = 0; l < bands; ++l) {
      const double a = sh::clampedCosineFactor(l);
      reference += a * a * (2 * l + 1) / (4.0 * M_PI);
    }
    reference = std::sqrt(reference);
  }

  // Traces point p into slot `slot` of `out` (thread-safe for distinct slots).
  void trace(const Point& p, Estimates& out, uint32_t slot) const {
    const VertexSampler sampler(liftedOrigin(p.position, p.normal, p.pull, extent), p.normal, seed, kRefineStream,
                                tnear);
    out.normal[slot] = p.normal;
    uint64_t* bits = &out.blocked[slot * out.words];
    alignas(64) Ray batch[kStream];
    for (uint32_t first = 0; first < samples; first += kStream) {
      const uint32_t count = std::min<uint32_t>(kStream, samples - first);
      for (uint32_t j = 0; j < count; ++j) sampler.make(first + j, batch[j]);
      rays.occluded(batch, count);
      for (uint32_t j = 0; j < count; ++j)
        if (batch[j].occludedHit()) bits[(first + j) / 64] |= uint64_t(1) << ((first + j) % 64);
    }
  }

  // The score of a candidate: point 0 (a midpoint or centroid) against the mean of points
  // 1..n-1 (the corners that interpolate there). Direction s of every point is the same sample
  // about its own normal, so per direction the paired difference of the visible light
  //   D_i,s = π [U_0,s y_i(ω_0,s) − Σ_c U_c,s y_i(ω_c,s) / (n−1)]     (U = unblocked)
  // has mean e_i, the interpolation error of the direct transfer t⁰, and its sample variance
  // gives e's standard error with the correlation of the shared directions included. The sum
  // runs over the directions some point sees, or (fewer to evaluate where most are seen) over
  // the blocked ones: e = e_unoccluded − (the same sum over B = 1 − U), e_unoccluded the
  // closed form. What is scored is e − v̄ e_unoccluded, v̄ the points' mean visible share:
  // the error visibility adds to the normals' own interpolation (the mesh as its author
  // shaded it), zero on a surface that sees the whole sky or none of it, whatever its
  // curvature, and zero where the points' visibility agrees on a flat surface.
  double score(const Estimates& est, const uint32_t* pts, int n) const {
    const double w = 1.0 / (n - 1);
    bool same = true;
    for (int c = 1; c < n; ++c) same = same && est.normal[pts[c]] == est.normal[pts[0]];
    Frame frame[4];
    double eu[sh::kMaxBands * sh::kMaxBands] = {};  // closed-form interpolation error of t_unoccluded
    float y[sh::kMaxBands * sh::kMaxBands];
    for (int c = 0; c < n; ++c) {
      frame[c] = Frame::fromNormal(est.normal[pts[c]]);
      if (same) continue;
      sh::evaluate(bands, est.normal[pts[c]], y);
      for (int l = 0; l < bands; ++l)
        for (int m = -l; m <= l; ++m)
          eu[sh::index(l, m)] += (c == 0 ? 1.0 : -w) * sh::clampedCosineFactor(l) * y[sh::index(l, m)];
    }
    // Visible shares, and which set of directions is the smaller one to sum over.
    uint64_t unionBlocked = 0, unionSeen = 0;
    double seen = 0.0;
    for (int c = 0; c < n; ++c) {
      uint64_t b = 0;
      for (size_t word = 0; word < est.words; ++word) b += uint64_t(std::popcount(est.blocked[pts[c] * est.words + word]));
      seen += double(samples - b) / samples;
    }
    seen /= n;
    const uint64_t tail = samples % 64 ? (uint64_t(1) << (samples % 64)) - 1 : ~uint64_t(0);
    for (size_t word = 0; word < est.words; ++word) {
      const uint64_t valid = word + 1 == est.words ? tail : ~uint64_t(0);
      uint64_t any = 0, none = 0;
      for (int c = 0; c < n; ++c) {
        any |= est.blocked[pts[c] * est.words + word];
        none |= ~est.blocked[pts[c] * est.words + word] & valid;
      }
      unionBlocked += uint64_t(std::popcount(any));
      unionSeen += uint64_t(std::popcount(none));
    }
    const bool overBlocked = unionBlocked <= unionSeen;  // sum over B, e = e_u − Σ
    double sum[sh::kMaxBands * sh::kMaxBands] = {}, sum2[sh::kMaxBands * sh::kMaxBands] = {};
    double d[sh::kMaxBands * sh::kMaxBands];
    for (size_t word = 0; word < est.words; ++word) {
      const uint64_t valid = word + 1 == est.words ? tail : ~uint64_t(0);
      uint64_t bits[4], any = 0, all = valid;
      for (int c = 0; c < n; ++c) {
        bits[c] = overBlocked ? est.blocked[pts[c] * est.words + word] : ~est.blocked[pts[c] * est.words + word] & valid;
        any |= bits[c];
        all &= bits[c];
      }
      if (same) any &= ~all;  // one direction for all points, in the set for all: no difference
      while (any) {
        const int s = int(word * 64) + std::countr_zero(any);
        const uint64_t bit = uint64_t(1) << (s % 64);
        any &= any - 1;
        if (same) {
          double k = bits[0] & bit ? 1.0 : 0.0;
          for (int c = 1; c < n; ++c) k -= bits[c] & bit ? w : 0.0;
          if (k == 0.0) continue;
          sh::evaluate(bands, frame[0].toWorld(local[size_t(s)]), y);
          for (int i = 0; i < n2; ++i) d[i] = k * y[i];
        } else {
          std::fill_n(d, n2, 0.0);
          for (int c = 0; c < n; ++c) {
            if (!(bits[c] & bit)) continue;
            sh::evaluate(bands, frame[c].toWorld(local[size_t(s)]), y);
            const double k = c == 0 ? 1.0 : -w;
            for (int i = 0; i < n2; ++i) d[i] += k * y[i];
          }
        }
        for (int i = 0; i < n2; ++i) {
          sum[i] += d[i];
          sum2[i] += d[i] * d[i];
        }
      }
    }
    const double ns = samples;
    double err2 = 0.0, var = 0.0;
    for (int i = 0; i < n2; ++i) {
      const double mean = M_PI * sum[i] / ns;
      const double e = (overBlocked ? eu[i] - mean : mean) - seen * eu[i];
      err2 += e * e;
      var += std::max(0.0, (M_PI * M_PI * sum2[i] / ns - mean * mean) / ns);
    }
    return (std::sqrt(err2) - kNoiseSigmas * std::sqrt(var)) / reference;
  }
};

// One baked instance while it is refined.
struct Work {
  size_t instance = 0;
  MeshInstance* m = nullptr;
  bool twoSided = false;  // both sides are baked (bakesBackSide): both are estimated and scored
  size_t originalVertices = 0;
  std::vector<glm::vec3> sourceNormals;  // the instance's normals before refinement
  std::vector<Blend> source;             // per vertex: the original vertices it interpolates
  std::vector<uint32_t> posId;           // per vertex: its position's id (equal positions, equal ids)
  std::vector<uint32_t> vertexEstimate;  // per vertex: its slot in the estimates
  std::unordered_map<uint64_t, uint32_t> edgeEstimate;  // index edge -> slot of its midpoint
  std::map<std::array<uint32_t, 3>, uint32_t> centroidEstimate;  // sorted corners -> slot
  // Rebuilt every round:
  // Position edge -> its triangles (in triangle order) and the number of distinct index edges on
  // it, as flat arrays sorted by edge (a hash map of vectors cost most of refinement in malloc).
  std::vector<uint64_t> edgeKeys;         // sorted, unique
  std::vector<uint32_t> edgeBegin;        // edgeKeys.size() + 1 offsets into edgeTriangles
  std::vector<uint32_t> edgeTriangles;
  std::vector<uint32_t> edgeIndexEdges;   // per edge: distinct index edges
  size_t edgeSlot(uint64_t pe) const {
    const auto it = std::lower_bound(edgeKeys.begin(), edgeKeys.end(), pe);
    PRT_CHECK(it != edgeKeys.end() && *it == pe);
    return size_t(it - edgeKeys.begin());
  }
  std::pair<const uint32_t*, const uint32_t*> trianglesOf(uint64_t pe) const {
    const size_t k = edgeSlot(pe);
    return {edgeTriangles.data() + edgeBegin[k], edgeTriangles.data() + edgeBegin[k + 1]};
  }
  std::vector<uint64_t> longest;  // per triangle: its longest position edge
  uint64_t added = 0;
};

struct PositionIds {
  struct Hash {
    size_t operator()(const std::array<uint32_t, 3>& k) const {
      return size_t(splitMix64(k[0] ^ splitMix64(k[1] ^ splitMix64(k[2]))));
    }
  };
  std::unordered_map<std::array<uint32_t, 3>, uint32_t, Hash> ids;
  uint32_t of(const glm::vec3& p) {
    std::array<uint32_t, 3> k;
    for (int c = 0; c < 3; ++c) {
      const float x = p[c] + 0.0f;  // -0 and +0 are one position
      std::memcpy(&k[size_t(c)], &x, 4);
    }
    return ids.emplace(k, uint32_t(ids.size())).first->second;
  }
};

double length2(const MeshInstance& m, uint32_t a, uint32_t b) {
  const glm::dvec3 d = glm::dvec3(m.positions[a]) - glm::dvec3(m.positions[b]);
  return glm::dot(d, d);
}

// The longer of two edges, ties broken by their position keys: the same answer on both sides
// of a shared edge.
bool longer(double l1, uint64_t k1, double l2, uint64_t k2) { return l1 != l2 ? l1 > l2 : k1 < k2; }

uint64_t posEdgeOf(const Work& w, uint32_t a, uint32_t b) { return edgeKey(w.posId[a], w.posId[b]); }

void buildAdjacency(Work& w) {
  const MeshInstance& m = *w.m;
  struct Corner {
    uint64_t pe, ie;
    uint32_t t;
  };
  std::vector<Corner> corners;
  corners.reserve(m.indices.size());
  w.longest.assign(m.triangleCount(), 0);
  for (uint32_t t = 0; t < m.triangleCount(); ++t) {
    const uint32_t* ix = &m.indices[3 * size_t(t)];
    double best = -1.0;
    for (int j = 0; j < 3; ++j) {
      const uint32_t a = ix[j], b = ix[(j + 1) % 3];
      const uint64_t pe = posEdgeOf(w, a, b);
      corners.push_back({pe, edgeKey(a, b), t});
      const double l = length2(m, a, b);
      if (best < 0.0 || longer(l, pe, best, w.longest[t])) {
        best = l;
        w.longest[t] = pe;
      }
    }
  }
  // Stable: a position edge's triangles stay in triangle order, as they were found.
  std::stable_sort(corners.begin(), corners.end(), [](const Corner& x, const Corner& y) { return x.pe < y.pe; });
  w.edgeKeys.clear();
  w.edgeBegin.clear();
  w.edgeTriangles.clear();
  w.edgeIndexEdges.clear();
  w.edgeTriangles.reserve(corners.size());
  std::vector<uint64_t> seen;
  for (size_t i = 0; i < corners.size();) {
    size_t j = i;
    seen.clear();
    w.edgeKeys.push_back(corners[i].pe);
    w.edgeBegin.push_back(uint32_t(w.edgeTriangles.size()));
    for (; j < corners.size() && corners[j].pe == corners[i].pe; ++j) {
      w.edgeTriangles.push_back(corners[j].t);
      if (std::find(seen.begin(), seen.end(), corners[j].ie) == seen.end()) seen.push_back(corners[j].ie);
    }
    w.edgeIndexEdges.push_back(uint32_t(seen.size()));
    i = j;
  }
  w.edgeBegin.push_back(uint32_t(w.edgeTriangles.size()));
}

glm::vec3 blendNormal(const Work& w, const Blend& b, const glm::vec3& fallback) {
  glm::vec3 n(0.0f);
  for (int j = 0; j < 3; ++j) n += b.weight[j] * w.sourceNormals[b.vertex[j]];
  const float len = glm::length(n);
  return len > 1e-12f ? n / len : fallback;
}

// A candidate: an edge's midpoint or a triangle's centroid, the position edge that splitting
// for it marks, its score.
struct Candidate {
  double score = 0.0;
  uint32_t work = 0;
  uint64_t posEdge = 0;
  uint64_t order = 0;  // where it was found (deterministic tie-break)
};

// Marks `pe` and its closure (the longest edge of every triangle beside a marked edge). Returns
// the vertices that adds; `undo` collects what was marked.
uint64_t markWithClosure(const Work& w, uint64_t pe, std::unordered_set<uint64_t>& marked, std::vector<uint64_t>& undo) {
  uint64_t cost = 0;
  std::vector<uint64_t> stack{pe};
  while (!stack.empty()) {
    const uint64_t e = stack.back();
    stack.pop_back();
    if (!marked.insert(e).second) continue;
    undo.push_back(e);
    cost += w.edgeIndexEdges[w.edgeSlot(e)];
    const auto [first, last] = w.trianglesOf(e);
    for (const uint32_t* t = first; t != last; ++t)
      if (!marked.count(w.longest[*t])) stack.push_back(w.longest[*t]);
  }
  return cost;
}

// Creates (once per index edge) the midpoint vertex of (a, b), with every attribute
// interpolated and the midpoint's estimate as its own.
uint32_t midpointVertex(Work& w, PositionIds& ids, std::unordered_map<uint64_t, uint32_t>& made, uint32_t a, uint32_t b) {
  const uint64_t key = edgeKey(a, b);
  if (auto it = made.find(key); it != made.end()) return it->second;
  MeshInstance& m = *w.m;
  const uint32_t v = uint32_t(m.positions.size());
  const glm::vec3 p = (m.positions[a] + m.positions[b]) * 0.5f;  // symmetric in a, b: seams stay closed
  const Blend s = mergeBlends({{&w.source[a], 0.5f}, {&w.source[b], 0.5f}});
  m.positions.push_back(p);
  m.normals.push_back(blendNormal(w, s, m.normals[a]));
  if (!m.texcoords.empty()) m.texcoords.push_back((m.texcoords[a] + m.texcoords[b]) * 0.5f);
  if (!m.colors.empty()) m.colors.push_back((m.colors[a] + m.colors[b]) * 0.5f);
  w.source.push_back(s);
  w.posId.push_back(ids.of(p));
  w.vertexEstimate.push_back(w.edgeEstimate.at(key));
  made.emplace(key, v);
  ++w.added;
  return v;
}

// Bisects triangle (v0, v1, v2) at its longest marked edge among vertices older than `old`,
// then its children at theirs; appends the result to `out`.
void splitTriangle(Work& w, PositionIds& ids, const std::unordered_set<uint64_t>& marked,
                   std::unordered_map<uint64_t, uint32_t>& made, uint32_t old, std::array<uint32_t, 3> t,
                   std::vector<uint32_t>& out) {
  int best = -1;
  double bestLen = 0.0;
  uint64_t bestKey = 0;
  for (int j = 0; j < 3; ++j) {
    const uint32_t a = t[size_t(j)], b = t[size_t((j + 1) % 3)];
    if (a >= old || b >= old) continue;
    const uint64_t pe = posEdgeOf(w, a, b);
    if (!marked.count(pe)) continue;
    const double l = length2(*w.m, a, b);
    if (best < 0 || longer(l, pe, bestLen, bestKey)) {
      best = j;
      bestLen = l;
      bestKey = pe;
    }
  }
  if (best < 0) {
    out.insert(out.end(), t.begin(), t.end());
    return;
  }
  const uint32_t a = t[size_t(best)], b = t[size_t((best + 1) % 3)], c = t[size_t((best + 2) % 3)];
  const uint32_t mid = midpointVertex(w, ids, made, a, b);
  splitTriangle(w, ids, marked, made, old, {a, mid, c}, out);
  splitTriangle(w, ids, marked, made, old, {mid, b, c}, out);
}

}  // namespace

uint64_t refineBudget(const RefineSettings& refine, const Scene& scene) {
  if (refine.budget > 0) return refine.budget;
  uint64_t vertices = 0;
  for (const MeshInstance& m : scene.meshes)
    if (!m.receiverOnly) vertices += m.vertexCount();
  return std::max(vertices, kMinAutoBudget);
}

void validate(const RefineSettings& s) {
  if (!std::isfinite(s.tolerance) || s.tolerance < 0.0)
    throw Error(cat("refine tolerance ", s.tolerance, ": must be a finite number >= 0 (0: no refinement)"));
  if (s.samples < 1 || s.samples > kMaxSamples)
    throw Error(cat("refine samples ", s.samples, ": must be between 1 and ", kMaxSamples));
}

void addRefineFingerprint(Fingerprint& fp, const RefineSettings& refine, const BakeSettings& bake) {
  if (refine.tolerance <= 0.0 || !bake.shadowed) {
    fp.add("refine", "no");
    return;
  }
  fp.add("refine tolerance", cat(refine.tolerance));
  fp.add("refine budget", std::to_string(refine.budget));
  fp.add("refine samples", std::to_string(std::min(refine.samples, bake.samples)));
}

RefineStats refineScene(Scene& scene, const RefineSettings& refine, const BakeSettings& bake, Checkpoint* checkpoint) {
  validate(refine);
  validate(bake);
  const auto t0 = Clock::now();
  RefineStats stats;
  std::vector<Work> works;
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if (m.receiverOnly) continue;
    stats.verticesBefore += m.vertexCount();
    stats.trianglesBefore += m.triangleCount();
  }
  stats.verticesAfter = stats.verticesBefore;
  stats.trianglesAfter = stats.trianglesBefore;
  stats.budget = refineBudget(refine, scene);
  if (refine.tolerance <= 0.0 || !bake.shadowed || stats.trianglesBefore == 0) return stats;

  const ThreadLimit threadLimit(bake.threads);
  const RayScene rays(scene);
  const float extent = rays.sceneExtent();
  const double minEdge2 = std::pow(2.0 * kMinEdgeShare * double(extent), 2.0);  // children >= kMinEdgeShare
  const Estimator estimator(rays, bake.bands, uint32_t(std::min(refine.samples, bake.samples)), bake.seed, extent);
  Estimates est;
  est.words = (estimator.samples + 63) / 64;
  std::vector<double> scoreOf;  // per point that is a candidate's midpoint or centroid; NaN: not yet
  PositionIds ids;

  // The vertices, with their bake ray origins (vertex_rays.h).
  std::vector<Point> todo;
  std::vector<uint32_t> todoSlot;
  // A new point to estimate, on both sides for a double-sided instance (the back: normal −n,
  // lifted along −n, as the bake's virtual vertices are); returns its front slot.
  auto addPoint = [&](bool twoSided, const Point& p) {
    const uint32_t slot = est.add();
    todo.push_back(p);
    todoSlot.push_back(slot);
    if (twoSided) {
      const uint32_t b = est.add();
      est.back[slot] = b;
      todo.push_back({p.position, -p.normal, p.pull});
      todoSlot.push_back(b);
    }
    return slot;
  };
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    MeshInstance& m = scene.meshes[k];
    if (m.receiverOnly) continue;
    Work w;
    w.instance = k;
    w.m = &m;
    w.twoSided = bakesBackSide(scene, m);
    w.originalVertices = m.vertexCount();
    w.sourceNormals = m.normals;
    w.source.resize(m.vertexCount());
    std::vector<glm::vec3> pull(m.vertexCount(), glm::vec3(0.0f));
    accumulatePull(m.positions, m.indices, pull.data());
    for (uint32_t v = 0; v < m.vertexCount(); ++v) {
      w.source[v].vertex[0] = v;
      w.posId.push_back(ids.of(m.positions[v]));
      w.vertexEstimate.push_back(addPoint(w.twoSided, {m.positions[v], m.normals[v], pull[v]}));
    }
    works.push_back(std::move(w));
  }

  // MPI ranks (ranks.h) trace every rank's share of the points, in blocks of kShareBlock
  // (taken from a shared counter on one host, block b on rank b mod N elsewhere), and trade
  // the blocked bits; shards, which run apart, each refine the whole scene.
  Ranks& spread = ranks();
  const bool shared = spread.exchanges();
  uint32_t pass = 0;  // the ranks' shared loops so far (refineCounterSlot)
  auto blocksOf = [](size_t n) { return (n + kShareBlock - 1) / kShareBlock; };
  auto evaluate = [&]() {
    if (!shared) {
      tbb::parallel_for(size_t(0), todo.size(), [&](size_t i) {
        if (!interruptRequested()) estimator.trace(todo[i], est, todoSlot[i]);
      });
    } else {
      std::vector<uint8_t> here(blocksOf(todo.size()), 0);
      forRankShare(spread.chunkCounter(refineCounterSlot(pass++)), here.size(), [&](uint64_t b) {
        for (size_t i = b * kShareBlock; i < std::min(todo.size(), (b + 1) * kShareBlock); ++i)
          estimator.trace(todo[i], est, todoSlot[i]);
        here[b] = 1;
      });
      stopIfInterrupted(checkpoint);
      // Per block traced here: u64 block, then each point's bits.
      const size_t bytes = est.words * sizeof(uint64_t);
      std::string mine;
      for (uint64_t b = 0; b < here.size(); ++b) {
        if (!here[b]) continue;
        mine.append(reinterpret_cast<const char*>(&b), sizeof b);
        for (size_t i = b * kShareBlock; i < std::min(todo.size(), (b + 1) * kShareBlock); ++i)
          mine.append(reinterpret_cast<const char*>(&est.blocked[todoSlot[i] * est.words]), bytes);
      }
      const std::vector<std::string> all = spread.gather(std::move(mine), true);
      for (size_t from = 0; from < all.size(); ++from) {
        if (int(from) == spread.rank()) continue;
        for (size_t at = 0; at < all[from].size();) {
          uint64_t b = 0;
          PRT_CHECK_LE(at + sizeof b, all[from].size());
          std::memcpy(&b, all[from].data() + at, sizeof b);
          at += sizeof b;
          PRT_CHECK_LT(b, here.size());
          for (size_t i = b * kShareBlock; i < std::min(todo.size(), (b + 1) * kShareBlock); ++i) {
            PRT_CHECK_LE(at + bytes, all[from].size());
            std::memcpy(&est.blocked[todoSlot[i] * est.words], all[from].data() + at, bytes);
            est.normal[todoSlot[i]] = todo[i].normal;
            at += bytes;
          }
        }
      }
    }
    stats.points += todo.size();
    stats.rays += uint64_t(todo.size()) * estimator.samples;
    todo.clear();
    todoSlot.clear();
    stopIfInterrupted(checkpoint);
  };
  evaluate();

  uint64_t left = stats.budget;
  for (int round = 0;; ++round) {
    // Candidates of the current meshes: estimate the new ones, score them all.
    std::vector<Candidate> candidates;
    struct Pending {
      uint32_t work;
      bool edge;
      uint64_t posEdge;
      std::array<uint32_t, 3> v;  // edge: a, b; triangle: corners
      uint32_t slot;
    };
    std::vector<Pending> pending;
    for (uint32_t wi = 0; wi < works.size(); ++wi) {
      Work& w = works[wi];
      const MeshInstance& m = *w.m;
      buildAdjacency(w);
      std::unordered_set<uint64_t> seen;
      std::set<std::array<uint32_t, 3>> seenTriangles;
      for (uint32_t t = 0; t < m.triangleCount(); ++t) {
        const uint32_t* ix = &m.indices[3 * size_t(t)];
        for (int j = 0; j < 3; ++j) {
          const uint32_t a = ix[j], b = ix[(j + 1) % 3];
          const uint64_t ie = edgeKey(a, b);
          if (length2(m, a, b) < minEdge2 || !seen.insert(ie).second) continue;
          auto [it, fresh] = w.edgeEstimate.emplace(ie, 0);
          if (fresh) {
            // Pulled towards the vertices opposite the edge, as a vertex there would be.
            glm::vec3 mid = (m.positions[a] + m.positions[b]) * 0.5f, pull(0.0f);
            const auto [first, last] = w.trianglesOf(posEdgeOf(w, a, b));
            for (const uint32_t* u = first; u != last; ++u) {
              const uint32_t* jx = &m.indices[3 * size_t(*u)];
              for (int c = 0; c < 3; ++c) {
                if (w.posId[jx[c]] == w.posId[a] || w.posId[jx[c]] == w.posId[b]) continue;
                const glm::vec3 d = m.positions[jx[c]] - mid;
                if (glm::length(d) > 0.0f) pull += glm::normalize(d);
              }
            }
            const Blend s = mergeBlends({{&w.source[a], 0.5f}, {&w.source[b], 0.5f}});
            it->second = addPoint(w.twoSided, {mid, blendNormal(w, s, m.normals[a]), pull});
          }
          pending.push_back({wi, true, posEdgeOf(w, a, b), {a, b, 0}, it->second});
        }
        // The centroid, when the triangle's longest edge may be split.
        const uint64_t le = w.longest[t];
        std::array<uint32_t, 3> corners{ix[0], ix[1], ix[2]};
        double l = 0.0;
        for (int j = 0; j < 3; ++j) l = std::max(l, length2(m, ix[j], ix[(j + 1) % 3]));
        if (l < minEdge2) continue;
        std::array<uint32_t, 3> sorted = corners;
        std::sort(sorted.begin(), sorted.end());
        if (!seenTriangles.insert(sorted).second) continue;  // a repeated triangle
        auto [it, fresh] = w.centroidEstimate.emplace(sorted, 0);
        if (fresh) {
          const float third = 1.0f / 3.0f;
          const Blend s = mergeBlends({{&w.source[ix[0]], third}, {&w.source[ix[1]], third}, {&w.source[ix[2]], third}});
          const glm::vec3 c = (m.positions[ix[0]] + m.positions[ix[1]] + m.positions[ix[2]]) / 3.0f;
          it->second = addPoint(w.twoSided, {c, blendNormal(w, s, m.normals[ix[0]]), glm::vec3(0.0f)});
        }
        pending.push_back({wi, false, le, corners, it->second});
      }
    }
    evaluate();
    // Scores of the new candidates (a candidate keeps its points, so its score, while it lasts).
    scoreOf.resize(est.normal.size(), std::nan(""));
    std::vector<uint8_t> scoredHere(shared ? pending.size() : 0, 0);
    auto scoreOne = [&](size_t i) {
      const Pending& p = pending[i];
      if (!std::isnan(scoreOf[p.slot])) return;
      const Work& w = works[p.work];
      uint32_t pts[4] = {p.slot, 0, 0, 0};
      const int corners = p.edge ? 2 : 3;
      for (int c = 0; c < corners; ++c) pts[c + 1] = w.vertexEstimate[p.v[size_t(c)]];
      double score = estimator.score(est, pts, corners + 1);
      if (est.back[p.slot] != Estimates::kNone) {  // a double-sided instance: the worse side counts
        uint32_t back[4];
        for (int c = 0; c <= corners; ++c) back[c] = est.back[pts[c]];
        score = std::max(score, estimator.score(est, back, corners + 1));
      }
      scoreOf[p.slot] = score;
      if (shared) scoredHere[i] = 1;
    };
    if (!shared) {
      tbb::parallel_for(size_t(0), pending.size(), scoreOne);
    } else {
      forRankShare(spread.chunkCounter(refineCounterSlot(pass++)), blocksOf(pending.size()), [&](uint64_t b) {
        for (size_t i = b * kShareBlock; i < std::min(pending.size(), (b + 1) * kShareBlock); ++i) scoreOne(i);
      });
    }
    if (shared) {  // MPI ranks score their share too (blocks of candidates, as the points) and trade scores
      std::string mine;
      for (size_t i = 0; i < pending.size(); ++i) {
        if (!scoredHere[i]) continue;
        const uint32_t slot = pending[i].slot;
        mine.append(reinterpret_cast<const char*>(&slot), sizeof slot);
        mine.append(reinterpret_cast<const char*>(&scoreOf[slot]), sizeof(double));
      }
      for (const std::string& from : spread.gather(std::move(mine), true))
        for (size_t at = 0; at + 12 <= from.size(); at += 12) {
          uint32_t slot = 0;
          std::memcpy(&slot, from.data() + at, 4);
          PRT_CHECK_LT(slot, scoreOf.size());
          std::memcpy(&scoreOf[slot], from.data() + at + 4, 8);
        }
    }
    double residual = 0.0;
    for (size_t i = 0; i < pending.size(); ++i) {
      const double score = scoreOf[pending[i].slot];
      residual = std::max(residual, score);
      if (score > refine.tolerance) candidates.push_back({score, pending[i].work, pending[i].posEdge, uint64_t(i)});
    }
    stats.residual = residual;
    if (candidates.empty() || left == 0 || round >= kMaxRefineRounds) {
      stats.budgetReached = !candidates.empty() && left == 0;
      break;
    }
    std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
      return x.score != y.score ? x.score > y.score : x.order < y.order;
    });
    std::vector<std::unordered_set<uint64_t>> marked(works.size());
    bool any = false;
    for (const Candidate& c : candidates) {
      std::vector<uint64_t> undo;
      const uint64_t cost = markWithClosure(works[c.work], c.posEdge, marked[c.work], undo);
      if (cost > left) {
        for (uint64_t e : undo) marked[c.work].erase(e);
        stats.budgetReached = true;
        break;
      }
      left -= cost;
      any = any || cost > 0;
    }
    if (!any) break;
    ++stats.rounds;
    for (uint32_t wi = 0; wi < works.size(); ++wi) {
      if (marked[wi].empty()) continue;
      Work& w = works[wi];
      MeshInstance& m = *w.m;
      const uint32_t old = uint32_t(m.vertexCount());
      std::unordered_map<uint64_t, uint32_t> made;
      std::vector<uint32_t> indices;
      indices.reserve(m.indices.size() * 2);
      for (size_t t = 0; t < m.triangleCount(); ++t)
        splitTriangle(w, ids, marked[wi], made, old, {m.indices[3 * t], m.indices[3 * t + 1], m.indices[3 * t + 2]},
                      indices);
      m.indices = std::move(indices);
      // The split edges' midpoints are vertices now; their halves are new edges.
      for (const auto& [key, v] : made) w.edgeEstimate.erase(key);
    }
  }

  // The refined instances: what they interpolate, in file vertices.
  stats.trianglesAfter = 0;
  for (Work& w : works) {
    MeshInstance& m = *w.m;
    stats.verticesAfter += w.added;
    stats.trianglesAfter += m.triangleCount();
    if (w.added == 0) continue;
    std::vector<Blend> file(m.vertexCount());
    for (size_t v = 0; v < file.size(); ++v) {
      Blend b = w.source[v];
      if (!m.fileVertex.empty())
        for (int j = 0; j < 3; ++j) b.vertex[j] = b.weight[j] != 0.0f ? m.fileVertex[b.vertex[j]] : 0;
      file[v] = mergeBlends({{&b, 1.0f}});
    }
    m.fileBlend = std::move(file);
    m.fileVertex.clear();
    m.transfer.clear();
  }
  stats.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return stats;
}

}  // namespace prt::bake
