// Adaptive refinement of the baked meshes (refine.h, docs/bake.md "Refinement").
//
// What is measured, and how a candidate (an edge's midpoint, a triangle's centroid) is scored:
// refine_estimator.cpp. Scores above the tolerance are split, largest first, until the budget
// is spent.
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
#include "prt/tangents.h"
#include "refine_estimator.h"
#include "stage_runner.h"
#include "unbury.h"
#include "vertex_rays.h"

namespace prt::bake {

namespace {

using Clock = std::chrono::steady_clock;
using Blend = MeshInstance::FileBlend;

using refinement::Estimates;
using refinement::Estimator;
using refinement::Point;

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

// One baked instance while it is refined.
struct Work {
  size_t instance = 0;
  MeshInstance* m = nullptr;
  bool twoSided = false;  // both sides are baked (bakesBackSide): both are estimated and scored
  size_t originalVertices = 0;
  std::vector<glm::vec3> sourceNormals;                 // the instance's normals before refinement
  std::vector<Blend> source;                            // per vertex: the original vertices it interpolates
  std::vector<uint32_t> posId;                          // per vertex: its position's id (equal positions, equal ids)
  std::vector<uint32_t> vertexEstimate;                 // per vertex: its slot in the estimates
  std::unordered_map<uint64_t, uint32_t> edgeEstimate;  // index edge -> slot of its midpoint
  std::map<std::array<uint32_t, 3>, uint32_t> centroidEstimate;  // sorted corners -> slot
  // Rebuilt every round:
  // Position edge -> its triangles (in triangle order) and the number of distinct index edges on
  // it, as flat arrays sorted by edge (a hash map of vectors cost most of refinement in malloc).
  std::vector<uint64_t> edgeKeys;   // sorted, unique
  std::vector<uint32_t> edgeBegin;  // edgeKeys.size() + 1 offsets into edgeTriangles
  std::vector<uint32_t> edgeTriangles;
  std::vector<uint32_t> edgeIndexEdges;  // per edge: distinct index edges
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
uint64_t markWithClosure(const Work& w, uint64_t pe, std::unordered_set<uint64_t>& marked,
                         std::vector<uint64_t>& undo) {
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
uint32_t midpointVertex(Work& w, PositionIds& ids, std::unordered_map<uint64_t, uint32_t>& made, uint32_t a,
                        uint32_t b) {
  const uint64_t key = edgeKey(a, b);
  if (auto it = made.find(key); it != made.end()) return it->second;
  MeshInstance& m = *w.m;
  const uint32_t v = uint32_t(m.positions.size());
  const glm::vec3 p = (m.positions[a] + m.positions[b]) * 0.5f;  // symmetric in a, b: seams stay closed
  const Blend s = mergeBlends({{&w.source[a], 0.5f}, {&w.source[b], 0.5f}});
  m.positions.push_back(p);
  m.normals.push_back(blendNormal(w, s, m.normals[a]));
  if (!m.texcoords.empty()) m.texcoords.push_back((m.texcoords[a] + m.texcoords[b]) * 0.5f);
  for (std::vector<glm::vec2>& set : m.moreTexcoords)
    if (!set.empty()) set.push_back((set[a] + set[b]) * 0.5f);
  if (!m.tangents.empty()) {  // the mean direction, made orthogonal to the new normal; a's handedness
    bool ok = false;
    const glm::vec3 t = orthogonalTangent(glm::vec3(m.tangents[a] + m.tangents[b]), m.normals.back(), ok);
    m.tangents.push_back(glm::vec4(t, m.tangents[a].w));
  }
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

// A candidate waiting for its score: an edge (a, b) or a triangle (its corners), the position
// edge splitting for it marks, and the slot of its midpoint or centroid.
struct Pending {
  uint32_t work;
  bool edge;
  uint64_t posEdge;
  std::array<uint32_t, 3> v;  // edge: a, b; triangle: corners
  uint32_t slot;
};

size_t blocksOf(size_t n) { return (n + kShareBlock - 1) / kShareBlock; }
// The end of block b of n items.
size_t blockEnd(uint64_t b, size_t n) { return std::min(n, (b + 1) * kShareBlock); }

}  // namespace

double refineScale(const Scene& scene) {
  std::array<std::vector<float>, 3> axis;
  for (const MeshInstance& m : scene.meshes)
    if (!m.receiverOnly)
      for (const glm::vec3& p : m.positions)
        for (int a = 0; a < 3; ++a) axis[size_t(a)].push_back(p[a]);
  if (axis[0].empty()) return 0.0;
  const size_t n = axis[0].size(), lo = size_t(kScaleOutliers * double(n - 1)), hi = n - 1 - lo;
  double d2 = 0.0;
  for (std::vector<float>& v : axis) {
    std::nth_element(v.begin(), v.begin() + ptrdiff_t(lo), v.end());
    const double low = v[lo];
    std::nth_element(v.begin(), v.begin() + ptrdiff_t(hi), v.end());
    d2 += std::pow(double(v[hi]) - low, 2.0);
  }
  return std::sqrt(d2);
}

namespace {

// One refinement: the baked instances being refined, every point estimated so far and the
// points waiting for their rays. run() repeats candidates → estimates → scores → splits.
class Refiner {
 public:
  Refiner(Scene& scene, const RefineSettings& refine, const BakeSettings& bake, Checkpoint* checkpoint,
          RefineStats& stats)
      : scene_(scene),
        refine_(refine),
        checkpoint_(checkpoint),
        stats_(stats),
        threadLimit_(bake.threads),
        rays_(scene),
        extent_(rays_.sceneExtent()),
        minEdge2_(std::pow(2.0 * kMinEdgeShare * refineScale(scene), 2.0)),  // children >= kMinEdgeShare
        estimator_(rays_, bake.bands, uint32_t(std::min(refine.samples, bake.samples)), bake.seed, extent_),
        spread_(ranks()),
        shared_(spread_.exchanges()),
        left_(stats.budget) {
    est_.words = (estimator_.samples() + 63) / 64;
  }

  void run() {
    addInstances();
    evaluate();
    for (int round = 0;; ++round) {
      const std::vector<Pending> pending = collectCandidates();
      evaluate();
      scoreNew(pending);
      std::vector<Candidate> candidates = overTolerance(pending);
      if (candidates.empty() || left_ == 0 || round >= kMaxRefineRounds) {
        stats_.budgetReached = !candidates.empty() && left_ == 0;
        break;
      }
      std::vector<std::unordered_set<uint64_t>> marked(works_.size());
      if (!markEdges(candidates, marked)) break;
      ++stats_.rounds;
      for (uint32_t wi = 0; wi < works_.size(); ++wi)
        if (!marked[wi].empty()) splitInstance(works_[wi], marked[wi]);
    }
    writeFileBlends();
  }

 private:
  // A new point to estimate, on both sides for a double-sided instance (the back: normal −n,
  // lifted along −n, as the bake's virtual vertices are); returns its front slot.
  uint32_t addPoint(bool twoSided, const Point& p) {
    const uint32_t slot = est_.add();
    todo_.push_back(p);
    todoSlot_.push_back(slot);
    if (twoSided) {
      const uint32_t b = est_.add();
      est_.back[slot] = b;
      Point back = p;
      back.normal = -p.normal;
      back.targets = 0;  // a back side keeps its origin (unbury.h)
      todo_.push_back(back);
      todoSlot_.push_back(b);
    }
    return slot;
  }

  // The baked instances and their vertices, with their bake ray origins (vertex_rays.h).
  void addInstances() {
    for (size_t k = 0; k < scene_.meshes.size(); ++k) {
      MeshInstance& m = scene_.meshes[k];
      if (m.receiverOnly) continue;
      Work w;
      w.instance = k;
      w.m = &m;
      w.twoSided = bakesBackSide(scene_, m);
      w.originalVertices = m.vertexCount();
      w.sourceNormals = m.normals;
      w.source.resize(m.vertexCount());
      std::vector<glm::vec3> pull(m.vertexCount(), glm::vec3(0.0f));
      accumulatePull(m.positions, m.indices, pull.data());
      const FanTargets fans(m.positions, m.indices);
      for (uint32_t v = 0; v < m.vertexCount(); ++v) {
        w.source[v].vertex[0] = v;
        w.posId.push_back(ids_.of(m.positions[v]));
        Point p{m.positions[v], m.normals[v], pull[v]};
        for (const glm::vec3& c : fans.of(v)) p.addTarget(c);
        w.vertexEstimate.push_back(addPoint(w.twoSided, p));
      }
      works_.push_back(std::move(w));
    }
  }

  // Traces the points waiting. MPI ranks (ranks.h) trace every rank's share of the points, in
  // blocks of kShareBlock (taken from a shared counter on one host, block b on rank b mod N
  // elsewhere), and trade the blocked bits; shards, which run apart, each refine the whole scene.
  void evaluate() {
    if (!shared_) {
      tbb::parallel_for(size_t(0), todo_.size(), [&](size_t i) {
        if (!interruptRequested()) estimator_.trace(todo_[i], est_, todoSlot_[i]);
      });
    } else {
      std::vector<uint8_t> here(blocksOf(todo_.size()), 0);
      forRankShare(spread_.chunkCounter(refineCounterSlot(pass_++)), here.size(), [&](uint64_t b) {
        for (size_t i = b * kShareBlock; i < blockEnd(b, todo_.size()); ++i)
          estimator_.trace(todo_[i], est_, todoSlot_[i]);
        here[b] = 1;
      });
      stopIfInterrupted(checkpoint_);
      exchangeBits(here);
    }
    stats_.points += todo_.size();
    stats_.rays += uint64_t(todo_.size()) * estimator_.samples();
    todo_.clear();
    todoSlot_.clear();
    stopIfInterrupted(checkpoint_);
  }

  // Sends the blocked bits of the blocks traced `here` (per block: u64 block, then each point's
  // bits) and takes the other ranks' blocks.
  void exchangeBits(const std::vector<uint8_t>& here) {
    const size_t bytes = est_.words * sizeof(uint64_t);
    std::string mine;
    for (uint64_t b = 0; b < here.size(); ++b) {
      if (!here[b]) continue;
      mine.append(reinterpret_cast<const char*>(&b), sizeof b);
      for (size_t i = b * kShareBlock; i < blockEnd(b, todo_.size()); ++i)
        mine.append(reinterpret_cast<const char*>(&est_.blocked[todoSlot_[i] * est_.words]), bytes);
    }
    const std::vector<std::string> all = spread_.gather(std::move(mine), true);
    for (size_t from = 0; from < all.size(); ++from) {
      if (int(from) == spread_.rank()) continue;
      for (size_t at = 0; at < all[from].size();) {
        uint64_t b = 0;
        PRT_CHECK_LE(at + sizeof b, all[from].size());
        std::memcpy(&b, all[from].data() + at, sizeof b);
        at += sizeof b;
        PRT_CHECK_LT(b, here.size());
        for (size_t i = b * kShareBlock; i < blockEnd(b, todo_.size()); ++i) {
          PRT_CHECK_LE(at + bytes, all[from].size());
          std::memcpy(&est_.blocked[todoSlot_[i] * est_.words], all[from].data() + at, bytes);
          est_.normal[todoSlot_[i]] = todo_[i].normal;
          at += bytes;
        }
      }
    }
  }

  // The candidates of the current meshes; new midpoints and centroids wait for their rays.
  std::vector<Pending> collectCandidates() {
    std::vector<Pending> pending;
    for (uint32_t wi = 0; wi < works_.size(); ++wi) {
      Work& w = works_[wi];
      buildAdjacency(w);
      std::unordered_set<uint64_t> seen;
      std::set<std::array<uint32_t, 3>> seenTriangles;
      for (uint32_t t = 0; t < w.m->triangleCount(); ++t) {
        addEdgeCandidates(wi, t, seen, pending);
        addCentroidCandidate(wi, t, seenTriangles, pending);
      }
    }
    return pending;
  }

  // The edges of triangle t not seen yet and long enough to split.
  void addEdgeCandidates(uint32_t wi, uint32_t t, std::unordered_set<uint64_t>& seen, std::vector<Pending>& pending) {
    Work& w = works_[wi];
    const MeshInstance& m = *w.m;
    const uint32_t* ix = &m.indices[3 * size_t(t)];
    for (int j = 0; j < 3; ++j) {
      const uint32_t a = ix[j], b = ix[(j + 1) % 3];
      const uint64_t ie = edgeKey(a, b);
      if (length2(m, a, b) < minEdge2_ || !seen.insert(ie).second) continue;
      auto [it, fresh] = w.edgeEstimate.emplace(ie, 0);
      if (fresh) it->second = addPoint(w.twoSided, midpointOf(w, a, b));
      pending.push_back({wi, true, posEdgeOf(w, a, b), {a, b, 0}, it->second});
    }
  }

  // The midpoint of edge (a, b), pulled towards the vertices opposite the edge, as a vertex
  // there would be.
  static Point midpointOf(const Work& w, uint32_t a, uint32_t b) {
    const MeshInstance& m = *w.m;
    glm::vec3 mid = (m.positions[a] + m.positions[b]) * 0.5f, pull(0.0f);
    Point p;
    p.addTarget(m.positions[a]);
    p.addTarget(m.positions[b]);
    const auto [first, last] = w.trianglesOf(posEdgeOf(w, a, b));
    for (const uint32_t* u = first; u != last; ++u) {
      const uint32_t* jx = &m.indices[3 * size_t(*u)];
      for (int c = 0; c < 3; ++c) {
        if (w.posId[jx[c]] == w.posId[a] || w.posId[jx[c]] == w.posId[b]) continue;
        p.addTarget(m.positions[jx[c]]);
        const glm::vec3 d = m.positions[jx[c]] - mid;
        if (glm::length(d) > 0.0f) pull += glm::normalize(d);
      }
    }
    const Blend s = mergeBlends({{&w.source[a], 0.5f}, {&w.source[b], 0.5f}});
    p.position = mid;
    p.normal = blendNormal(w, s, m.normals[a]);
    p.pull = pull;
    return p;
  }

  // The centroid of triangle t, when its longest edge may be split and it is not a repeat.
  void addCentroidCandidate(uint32_t wi, uint32_t t, std::set<std::array<uint32_t, 3>>& seenTriangles,
                            std::vector<Pending>& pending) {
    Work& w = works_[wi];
    const MeshInstance& m = *w.m;
    const uint32_t* ix = &m.indices[3 * size_t(t)];
    const uint64_t le = w.longest[t];
    std::array<uint32_t, 3> corners{ix[0], ix[1], ix[2]};
    double l = 0.0;
    for (int j = 0; j < 3; ++j) l = std::max(l, length2(m, ix[j], ix[(j + 1) % 3]));
    if (l < minEdge2_) return;
    std::array<uint32_t, 3> sorted = corners;
    std::sort(sorted.begin(), sorted.end());
    if (!seenTriangles.insert(sorted).second) return;  // a repeated triangle
    auto [it, fresh] = w.centroidEstimate.emplace(sorted, 0);
    if (fresh) {
      const float third = 1.0f / 3.0f;
      const Blend s = mergeBlends({{&w.source[ix[0]], third}, {&w.source[ix[1]], third}, {&w.source[ix[2]], third}});
      const glm::vec3 c = (m.positions[ix[0]] + m.positions[ix[1]] + m.positions[ix[2]]) / 3.0f;
      Point p{c, blendNormal(w, s, m.normals[ix[0]]), glm::vec3(0.0f)};
      for (int j = 0; j < 3; ++j) p.addTarget(m.positions[ix[j]]);
      it->second = addPoint(w.twoSided, p);
    }
    pending.push_back({wi, false, le, corners, it->second});
  }

  // Scores the new candidates (a candidate keeps its points, so its score, while it lasts).
  // MPI ranks score their share too (blocks of candidates, as the points) and trade scores.
  void scoreNew(const std::vector<Pending>& pending) {
    scoreOf_.resize(est_.normal.size(), std::nan(""));
    if (!shared_) {
      tbb::parallel_for(size_t(0), pending.size(), [&](size_t i) { scoreOne(pending[i]); });
      return;
    }
    std::vector<uint8_t> scoredHere(pending.size(), 0);
    forRankShare(spread_.chunkCounter(refineCounterSlot(pass_++)), blocksOf(pending.size()), [&](uint64_t b) {
      for (size_t i = b * kShareBlock; i < blockEnd(b, pending.size()); ++i) scoredHere[i] = scoreOne(pending[i]);
    });
    std::string mine;
    for (size_t i = 0; i < pending.size(); ++i) {
      if (!scoredHere[i]) continue;
      const uint32_t slot = pending[i].slot;
      mine.append(reinterpret_cast<const char*>(&slot), sizeof slot);
      mine.append(reinterpret_cast<const char*>(&scoreOf_[slot]), sizeof(double));
    }
    for (const std::string& from : spread_.gather(std::move(mine), true))
      for (size_t at = 0; at + 12 <= from.size(); at += 12) {
        uint32_t slot = 0;
        std::memcpy(&slot, from.data() + at, 4);
        PRT_CHECK_LT(slot, scoreOf_.size());
        std::memcpy(&scoreOf_[slot], from.data() + at + 4, 8);
      }
  }

  // Scores candidate p unless it has its score; a double-sided instance's worse side counts.
  // Returns whether it scored.
  bool scoreOne(const Pending& p) {
    if (!std::isnan(scoreOf_[p.slot])) return false;
    const Work& w = works_[p.work];
    uint32_t pts[4] = {p.slot, 0, 0, 0};
    const int corners = p.edge ? 2 : 3;
    for (int c = 0; c < corners; ++c) pts[c + 1] = w.vertexEstimate[p.v[size_t(c)]];
    double score = estimator_.score(est_, pts, corners + 1);
    if (est_.back[p.slot] != Estimates::kNone) {
      uint32_t back[4];
      for (int c = 0; c <= corners; ++c) back[c] = est_.back[pts[c]];
      score = std::max(score, estimator_.score(est_, back, corners + 1));
    }
    scoreOf_[p.slot] = score;
    return true;
  }

  // The candidates above the tolerance; records the largest score as the residual.
  std::vector<Candidate> overTolerance(const std::vector<Pending>& pending) {
    std::vector<Candidate> candidates;
    double residual = 0.0;
    for (size_t i = 0; i < pending.size(); ++i) {
      const double score = scoreOf_[pending[i].slot];
      residual = std::max(residual, score);
      if (score > refine_.tolerance) candidates.push_back({score, pending[i].work, pending[i].posEdge, uint64_t(i)});
    }
    stats_.residual = residual;
    return candidates;
  }

  // Marks the candidates' edges with their closure, largest scores first, while the budget
  // lasts. Returns whether any vertex will be added.
  bool markEdges(std::vector<Candidate>& candidates, std::vector<std::unordered_set<uint64_t>>& marked) {
    std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
      return x.score != y.score ? x.score > y.score : x.order < y.order;
    });
    bool any = false;
    for (const Candidate& c : candidates) {
      std::vector<uint64_t> undo;
      const uint64_t cost = markWithClosure(works_[c.work], c.posEdge, marked[c.work], undo);
      if (cost > left_) {
        for (uint64_t e : undo) marked[c.work].erase(e);
        stats_.budgetReached = true;
        break;
      }
      left_ -= cost;
      any = any || cost > 0;
    }
    return any;
  }

  // Splits the marked edges of one instance.
  void splitInstance(Work& w, const std::unordered_set<uint64_t>& marked) {
    MeshInstance& m = *w.m;
    const uint32_t old = uint32_t(m.vertexCount());
    std::unordered_map<uint64_t, uint32_t> made;
    std::vector<uint32_t> indices;
    indices.reserve(m.indices.size() * 2);
    for (size_t t = 0; t < m.triangleCount(); ++t)
      splitTriangle(w, ids_, marked, made, old, {m.indices[3 * t], m.indices[3 * t + 1], m.indices[3 * t + 2]},
                    indices);
    m.indices = std::move(indices);
    // The split edges' midpoints are vertices now; their halves are new edges.
    for (const auto& [key, v] : made) w.edgeEstimate.erase(key);
  }

  // The refined instances: what they interpolate, in file vertices.
  void writeFileBlends() {
    stats_.trianglesAfter = 0;
    for (Work& w : works_) {
      MeshInstance& m = *w.m;
      stats_.verticesAfter += w.added;
      stats_.trianglesAfter += m.triangleCount();
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
  }

  Scene& scene_;
  const RefineSettings& refine_;
  Checkpoint* checkpoint_;
  RefineStats& stats_;
  const ThreadLimit threadLimit_;
  const RayScene rays_;
  const float extent_;
  const double minEdge2_;
  const Estimator estimator_;
  Estimates est_;
  std::vector<double> scoreOf_;  // per point that is a candidate's midpoint or centroid; NaN: not yet
  PositionIds ids_;
  std::vector<Work> works_;
  std::vector<Point> todo_;  // points waiting for their rays, and their slots
  std::vector<uint32_t> todoSlot_;
  Ranks& spread_;
  const bool shared_;
  uint32_t pass_ = 0;  // the ranks' shared loops so far (refineCounterSlot)
  uint64_t left_;      // vertices the budget still allows
};

// The instances' sizes before refinement, and the budget.
RefineStats initialStats(const Scene& scene, const RefineSettings& refine) {
  RefineStats stats;
  for (const MeshInstance& m : scene.meshes) {
    if (m.receiverOnly) continue;
    stats.verticesBefore += m.vertexCount();
    stats.trianglesBefore += m.triangleCount();
  }
  stats.verticesAfter = stats.verticesBefore;
  stats.trianglesAfter = stats.trianglesBefore;
  stats.budget = refineBudget(refine, scene);
  return stats;
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
  RefineStats stats = initialStats(scene, refine);
  if (refine.tolerance <= 0.0 || !bake.shadowed || stats.trianglesBefore == 0) return stats;
  Refiner(scene, refine, bake, checkpoint, stats).run();
  stats.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return stats;
}

}  // namespace prt::bake
