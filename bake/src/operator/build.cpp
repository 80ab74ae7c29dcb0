// Building the bounce operator (prt/bake/bounce_operator.h): the clusters and trees (tree.cpp),
// then every vertex side's gather rays, read from the bake's own record of them (or traced
// where it has none), each row compressed as soon as it is made so that no gather outlives its
// cluster.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <queue>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include "../stage_runner.h"
#include "../surface_layout.h"
#include "../vertex_rays.h"
#include "probe_rows.h"
#include "prt/bake/bounce_operator.h"
#include "prt/bake/ranks.h"
#include "prt/error.h"
#include "prt/light.h"
#include "row_maker.h"
#include "training.h"
#include "tree.h"

namespace prt::bake {

void validate(const OperatorSettings& s) {
  auto within = [](const char* what, int v, int lo, int hi) {
    if (v < lo || v > hi) throw Error(cat(what, " ", v, ": must be between ", lo, " and ", hi));
  };
  within("operator samples", s.samples, 1, 16777216);
  within("operator cluster size", s.clusterSize, 0, 65536);
  within("operator row length", s.rowLength, 0, BounceOperator::kMaxRowLength);
  within("operator cluster row length", s.clusterRowLength, 1, BounceOperator::kMaxRowLength);
  within("operator gradient row length", s.gradientRowLength, 0, BounceOperator::kMaxRowLength);
  within("operator sky bins across", s.skyWidth, 1, 1024);
  within("operator sky bins down", s.skyHeight, 1, 1024);
  within("operator sample points", s.samplePoints, 1, 64);
  within("operator probe samples", s.probeSamples, 1, 16777216);
  within("operator probe row length", s.probeRowLength, 1, BounceOperator::kMaxRowLength);
  if (s.threads < 0) throw Error(cat("threads ", s.threads, ": must be 0 (all cores) or more"));
}

int clusterSizeFor(int clusterSize, uint64_t vertexSides) {
  if (clusterSize > 0) return clusterSize;
  return vertexSides <= kSmallScenesSides ? kSmallClusterSize : kLargeClusterSize;
}

namespace {

using op::Entry;
using op::mergeEntries;
using op::RowMaker;
using op::Tree;

// out = Σ_i coef[i] · rows[i] over the first n rows, each sorted by leaf with each leaf once (as
// mergeEntries leaves them): a k-way merge, sorted by leaf with each leaf once.
void weightedSum(const std::vector<std::vector<Entry>>& rows, size_t n, const std::vector<double>& coef,
                 std::vector<Entry>& out) {
  out.clear();
  std::vector<size_t> at(n, 0);
  for (;;) {
    uint32_t leaf = UINT32_MAX;
    for (size_t i = 0; i < n; ++i)
      if (at[i] < rows[i].size()) leaf = std::min(leaf, rows[i][at[i]].leaf);
    if (leaf == UINT32_MAX) return;
    double w = 0.0;
    for (size_t i = 0; i < n; ++i)
      if (at[i] < rows[i].size() && rows[i][at[i]].leaf == leaf) w += coef[i] * double(rows[i][at[i]++].w);
    out.push_back({leaf, float(w)});
  }
}

// Vertex sides as the clustering sees them: position, side normal, a third of the area of each
// triangle around the vertex, diffuse albedo at the vertex.
std::vector<op::SidePoint> sidePoints(const Scene& scene, const Layout& lay) {
  std::vector<op::SidePoint> sides(lay.vertices);
  const std::vector<float> area = op::sideAreas(scene, lay);
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    if (lay.vertexOffset[k] == SIZE_MAX) continue;
    const MeshInstance& m = scene.meshes[k];
    for (size_t offset : {lay.vertexOffset[k], lay.backVertexOffset[k]}) {
      if (offset == SIZE_MAX) continue;
      for (uint32_t v = 0; v < m.vertexCount(); ++v) {
        op::SidePoint& s = sides[offset + v];
        s.position = m.positions[v];
        s.normal = normalOf(scene, lay, offset + v);
        s.area = area[offset + v];
        s.albedo = albedoAtVertex(scene, m, v);
      }
    }
  }
  return sides;
}

struct Trace {
  const Scene& scene;
  const Layout& lay;
  const Tree& tree;
  const BounceOperator& op;
  const RayScene& rays;
  const std::vector<glm::vec3>& origins;
  float tnear;
  uint64_t seed;
  uint32_t K;
  const GatherRecords* kept;  // the bake's record of the same rays, or null

  // Vertex side v's gather: its K rays' shares of clusters (barycentric, at the hit's three
  // vertex sides) and of sky bins (bilinear), each ray 1/K. A ray that hits the back of a
  // one-sided face sends nothing.
  void gather(size_t v, std::vector<Entry>& out) const {
    out.clear();
    const VertexSampler sampler(origins[v], normalOf(scene, lay, v), seed, v, tnear);
    const float w = 1.0f / float(K);
    auto escaped = [&](uint32_t, const Ray& r) {
      op::splatSky(r.dir, op.skyWidth, op.skyHeight, [&](uint32_t bin, float share) {
        out.push_back({tree.skyLeafOfBin[bin], w * share});
      });
    };
    auto hit = [&](uint32_t tri, uint16_t q1, uint16_t q2) {
      const float b1 = q1 / 65535.0f, b2 = q2 / 65535.0f;
      const uint32_t* tv = &lay.triVerts[3 * size_t(tri)];
      out.push_back({tree.clusterOf[tv[0]], w * (1.0f - b1 - b2)});
      out.push_back({tree.clusterOf[tv[1]], w * b1});
      out.push_back({tree.clusterOf[tv[2]], w * b2});
    };
    if (kept && kept->rays == K && kept->of(v))
      replayGatherRays(*kept, v, sampler, escaped, hit);
    else
      traceGatherRays(rays, lay, sampler, K, escaped, hit);
    mergeEntries(out);
  }
};

// A vertex side keeps a row of its own (where rows of their own are asked for) when its cluster's
// light, shaded by its transfer shares and placed on the cluster's plane, misses what its own
// gather receives under the training lights by more than this share of the light it gets.
constexpr double kOwnRowError = 0.05;

// What a cluster's rows gather under the training lights, from surfaces and from the sky apart:
// its mean and its two gradients.
struct ClusterLight {
  using Values = std::array<double, RowMaker::K>;
  Values surface, sky, surfaceU, skyU, surfaceV, skyV;
  ClusterLight(const RowMaker& m, const std::vector<Entry>& mean, const std::vector<Entry>& u,
               const std::vector<Entry>& v) {
    m.values(mean, surface, sky);
    m.values(u, surfaceU, skyU);
    m.values(v, surfaceV, skyV);
  }
  // The mean over the training lights of |what the gather `raw` receives − the cluster's light
  // at (s, t) on its plane, shaded by the side's shares (`bs` of the surfaces', `ss` of the sky's)|.
  double error(const RowMaker& m, const std::vector<Entry>& raw, double bs, double ss, glm::vec2 st) const {
    Values own, ownSky;
    m.values(raw, own, ownSky);
    double err = 0.0;
    for (size_t k = 0; k < size_t(RowMaker::K); ++k)
      err += std::fabs(own[k] + ownSky[k] - bs * (surface[k] + st.x * surfaceU[k] + st.y * surfaceV[k]) -
                       ss * (sky[k] + st.x * skyU[k] + st.y * skyV[k]));
    return err / RowMaker::K;
  }
};

// The least-squares plane through a cluster's member gathers (`raw`, with their area shares and
// their places `st` in the cluster's frame, centred there): its two gradients, as leaf entries.
void planeOf(const std::vector<std::vector<Entry>>& raw, const std::vector<float>& share,
             const std::vector<glm::vec2>& st, std::vector<Entry>& gu, std::vector<Entry>& gv) {
  gu.clear(), gv.clear();
  double m00 = 0.0, m01 = 0.0, m11 = 0.0;
  for (size_t i = 0; i < share.size(); ++i) {
    m00 += double(share[i]) * st[i].x * st[i].x;
    m01 += double(share[i]) * st[i].x * st[i].y;
    m11 += double(share[i]) * st[i].y * st[i].y;
  }
  const double reg = 1e-3 * (m00 + m11);
  const double det = (m00 + reg) * (m11 + reg) - m01 * m01;
  if (!(m00 + m11 > 1e-6) || !(det > 0.0)) return;
  const double i00 = (m11 + reg) / det, i01 = -m01 / det, i11 = (m00 + reg) / det;
  std::vector<double> cu(share.size()), cv(share.size());
  for (size_t i = 0; i < share.size(); ++i) {
    cu[i] = share[i] * (i00 * st[i].x + i01 * st[i].y);
    cv[i] = share[i] * (i01 * st[i].x + i11 * st[i].y);
  }
  weightedSum(raw, share.size(), cu, gu);
  weightedSum(raw, share.size(), cv, gv);
}

// A cluster's gather: each member's (raw), their area shares of the cluster and places in its
// frame, and the cluster's own, their area-weighted mean (the plain mean without area).
struct ClusterGather {
  std::vector<std::vector<Entry>> raw;
  std::vector<Entry> all;
  std::vector<float> share;
  std::vector<glm::vec2> st;
  void make(const Trace& trace, const std::vector<float>& area, const std::vector<glm::vec2>& where, uint32_t c) {
    const BounceOperator& op = trace.op;
    const uint32_t b = op.memberStart[c], e = op.memberStart[c + 1];
    const float clusterArea = op.leafWeight[c];
    raw.resize(std::max<size_t>(raw.size(), e - b));
    share.clear(), st.clear();
    for (uint32_t i = b; i < e; ++i) {
      const uint32_t v = op.members[i];
      trace.gather(v, raw[i - b]);
      share.push_back(clusterArea > 1e-30f ? area[v] / clusterArea : 1.0f / float(e - b));
      st.push_back(where[v]);
    }
    weightedSum(raw, e - b, std::vector<double>(share.begin(), share.end()), all);
  }
};

// How the cluster rows are cut (RowMaker::make): at most `length` entries, splitting while the
// wrongest entry's error is at least `above`.
struct RowCut {
  size_t length;
  float above;
};

struct RowCutInputs {
  const Trace& trace;
  const BounceOperator& op;
  const Tree& tree;
  const std::vector<uint8_t>& sky;
  const op::Training& training;
  const std::vector<float>& area;
  const std::vector<glm::vec2>& st;
};

// The cut that holds the cluster rows to `perRow` entries a row on average, each at most
// kMaxRowLength: the entries go to the rows whose cuts would otherwise merge the most light, and
// a row that reaches few leaves leaves its share to others. Found on a sample of the clusters
// (every k-th, at least kSampled of them, or all), each row cut to kMaxRowLength with its splits
// recorded: a row's splits are taken in order, each at the least error of its row's splits up
// to it, and the splits of the largest such errors are kept while the sampled rows fit perRow
// entries each. The errors are binned by their float's top 14 bits (monotone for errors ≥ 0:
// 32 bins an octave), so the sample costs a small fixed table, not a list of its splits; `above`
// is the lower edge of the lowest bin kept whole. The same on every MPI rank.
RowCut rowCut(const RowCutInputs& in, size_t perRow) {
  constexpr uint32_t kSampled = 4096;
  constexpr int kShift = 18;
  constexpr size_t kBins = size_t(1) << (32 - kShift);
  auto binOf = [](float error) {
    uint32_t u = 0;
    std::memcpy(&u, &error, sizeof u);
    return u >> kShift;
  };
  const uint32_t C = in.op.clusters, stride = std::max<uint32_t>(1, C / kSampled), n = (C + stride - 1) / stride;
  struct Tally {
    std::vector<uint32_t> grows = std::vector<uint32_t>(kBins, 0);  // per bin: the entries its splits add
    uint64_t base = 0;                                              // the rows' lengths before any split
  };
  tbb::combinable<Tally> tallies;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, n, 4), [&](const tbb::blocked_range<uint32_t>& r) {
    Tally& t = tallies.local();
    RowMaker maker(in.op, in.tree, in.sky, in.training);
    ClusterGather g;
    std::vector<op::Split> splits;
    for (uint32_t k = r.begin(); k != r.end(); ++k) {
      const uint32_t c = k * stride;
      g.make(in.trace, in.area, in.st, c);
      const std::vector<Entry> row = maker.make(g.all, in.tree.center[c], BounceOperator::kMaxRowLength, &splits);
      t.base += splits.empty() ? row.size() : splits[0].before;
      float least = std::numeric_limits<float>::infinity();
      for (size_t i = 0; i < splits.size(); ++i) {
        const size_t after = i + 1 < splits.size() ? splits[i + 1].before : row.size();
        least = std::min(least, std::max(splits[i].priority, 0.0f));
        t.grows[binOf(least)] += uint32_t(after - splits[i].before);
      }
    }
  });
  Tally all;
  tallies.combine_each([&](const Tally& t) {
    all.base += t.base;
    for (size_t b = 0; b < kBins; ++b) all.grows[b] += t.grows[b];
  });
  uint64_t total = all.base;
  for (size_t b = kBins; b-- > 0;) {
    if (total + all.grows[b] > perRow * uint64_t(n)) {
      // Keep the bins above b: errors from b + 1's lower edge up (no bin above: no split).
      if (b + 1 == kBins) return {BounceOperator::kMaxRowLength, std::numeric_limits<float>::infinity()};
      const uint32_t edge = uint32_t(b + 1) << kShift;
      float above = 0.0f;
      std::memcpy(&above, &edge, sizeof above);
      return {BounceOperator::kMaxRowLength, above};
    }
    total += all.grows[b];
  }
  return {BounceOperator::kMaxRowLength, 0.0f};
}

// MPI ranks (prt/bake/ranks.h) that build one operator together: each makes the rows of the
// chunks of kRankChunk clusters it owns, and rank 0 receives the others' rows, the same rows
// one process makes (each is a function of its cluster alone).
constexpr uint32_t kRankChunk = 64;

struct MadeRows {
  std::vector<std::vector<Entry>>&vertex, &cluster, &gradient;
};

template <class T>
void append(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof v);
}
void appendRow(std::string& out, const std::vector<Entry>& row) {
  append(out, uint32_t(row.size()));
  out.append(reinterpret_cast<const char*>(row.data()), row.size() * sizeof(Entry));
}

// Every rank's rows to rank 0, which fills its lists with the clusters it did not make.
void shareRows(const BounceOperator& op, MadeRows made) {
  Ranks& r = ranks();
  std::string mine;
  for (uint32_t c = 0; c < op.clusters; ++c) {
    if (!r.owns(c / kRankChunk)) continue;
    append(mine, c);
    appendRow(mine, made.cluster[c]);
    appendRow(mine, made.gradient[2 * size_t(c)]);
    appendRow(mine, made.gradient[2 * size_t(c) + 1]);
    for (uint32_t i = op.memberStart[c]; i < op.memberStart[c + 1]; ++i) appendRow(mine, made.vertex[op.members[i]]);
  }
  const std::vector<std::string> all = r.gather(std::move(mine), false);
  for (size_t from = 1; from < all.size(); ++from) {
    const std::string& in = all[from];
    size_t at = 0;
    auto take = [&](auto& v) {
      PRT_CHECK_LE(at + sizeof v, in.size());
      std::memcpy(&v, in.data() + at, sizeof v);
      at += sizeof v;
    };
    auto takeRow = [&](std::vector<Entry>& row) {
      uint32_t n = 0;
      take(n);
      PRT_CHECK_LE(at + n * sizeof(Entry), in.size());
      row.resize(n);
      std::memcpy(row.data(), in.data() + at, n * sizeof(Entry));
      at += n * sizeof(Entry);
    };
    while (at < in.size()) {
      uint32_t c = 0;
      take(c);
      PRT_CHECK_LT(c, op.clusters);
      takeRow(made.cluster[c]);
      takeRow(made.gradient[2 * size_t(c)]);
      takeRow(made.gradient[2 * size_t(c) + 1]);
      for (uint32_t i = op.memberStart[c]; i < op.memberStart[c + 1]; ++i) takeRow(made.vertex[op.members[i]]);
    }
  }
}

// Rows as the operator holds them: weights w · one, on the one-byte codes' values with each
// row's sum kept (`held`: BounceOperator::storedWeights or storedGradients), or rounded where
// `exact` (an uncompressed operator, never stored). Entries held at 0 are dropped.
template <class Rows, class Held>
void storeRows(Rows& rows, const std::vector<std::vector<Entry>>& made, double one, bool exact, Held held) {
  rows.start.assign(1, 0);
  rows.node.clear(), rows.weight.clear();
  std::vector<double> scaled;
  for (const std::vector<Entry>& row : made) {
    scaled.clear();
    for (const Entry& e : row) scaled.push_back(double(e.w) * one);
    const auto weights = held(scaled, exact);
    for (size_t i = 0; i < row.size(); ++i) {
      if (weights[i] == 0) continue;
      rows.node.push_back(row[i].leaf);
      rows.weight.push_back(weights[i]);
    }
    rows.start.push_back(uint32_t(rows.node.size()));
  }
}

// The made rows into `op`: vertex and cluster rows, and gradient rows where made.
void storeAll(BounceOperator& op, MadeRows made, bool withGradients, bool exact) {
  const double one = BounceOperator::kWeightOne;
  storeRows(op.vertexRows, made.vertex, one, exact, BounceOperator::storedWeights);
  storeRows(op.clusterRows, made.cluster, one, exact, BounceOperator::storedWeights);
  if (withGradients)
    storeRows(op.clusterGradients, made.gradient, BounceOperator::kGradientOne, exact, BounceOperator::storedGradients);
}

}  // namespace

BounceOperator buildBounceOperator(const Scene& scene, const OperatorSettings& s, int bounces, uint64_t seed,
                                   bool uncompressed, const ProbeGrid* probes, ProbeShRows* probeSh,
                                   const GatherRecords* kept) {
  validate(s);
  const ThreadLimit threadLimit(s.threads);
  const Layout lay = makeLayout(scene);
  if (lay.vertices == 0) throw Error("bounce operator: the scene has no baked vertices");
  BounceOperator op;
  op.samples = s.samples, op.bounces = bounces, op.seed = seed;
  op.clusterSize = clusterSizeFor(s.clusterSize, lay.vertices), op.rowLength = s.rowLength,
  op.clusterRowLength = s.clusterRowLength;
  op.gradientRowLength = s.gradientRowLength;
  op.skyWidth = s.skyWidth, op.skyHeight = s.skyHeight, op.samplePoints = s.samplePoints;
  op.vertexSides = uint32_t(lay.vertices);
  const RayScene rays(scene);
  const std::vector<glm::vec3> origins = rayOrigins(scene, lay, rays);
  const op::SideTraining sideTraining = op::trainSides(scene, lay, rays, origins);
  const std::vector<op::SidePoint> sides = sidePoints(scene, lay);
  const Tree tree = op::buildTree(op, sides);
  const std::vector<uint8_t> sky = skyNodeMask(op);
  const Trace trace{scene, lay, tree, op, rays, origins, tnearFor(rays.sceneExtent()), seed, uint32_t(s.samples), kept};
  std::vector<float> area(sides.size());
  for (size_t v = 0; v < sides.size(); ++v) area[v] = sides[v].area;
  const op::Training training = op::trainNodes(scene, op, sideTraining, area);
  const op::TransferShares shares = op::transferShares(scene, lay, op, area);
  const std::vector<glm::vec2> st = op::clusterCoordinates(scene, lay, op, area);
  const size_t gradientLength = uncompressed ? SIZE_MAX : size_t(s.gradientRowLength);
  const size_t vertexLength = uncompressed ? SIZE_MAX : size_t(s.rowLength);
  const RowCut cut = uncompressed ? RowCut{SIZE_MAX, 0.0f}
                                  : rowCut({trace, op, tree, sky, training, area, st}, size_t(s.clusterRowLength));
  std::vector<std::vector<Entry>> vertexRows(lay.vertices), clusterRows(op.clusters), gradients(2 * op.clusters);
  const bool shared = ranks().exchanges() && ranks().size() > 1;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, op.clusters, 4), [&](const tbb::blocked_range<uint32_t>& r) {
    RowMaker maker(op, tree, sky, training);
    ClusterGather g;
    std::vector<Entry> gu, gv;
    for (uint32_t c = r.begin(); c != r.end(); ++c) {
      if (shared && !ranks().owns(c / kRankChunk)) continue;
      g.make(trace, area, st, c);
      clusterRows[c] = maker.make(g.all, tree.center[c], cut.length, nullptr, cut.above);
      if (gradientLength > 0) {
        planeOf(g.raw, g.share, g.st, gu, gv);
        gradients[2 * c] = maker.make(gu, tree.center[c], gradientLength);
        gradients[2 * c + 1] = maker.make(gv, tree.center[c], gradientLength);
      }
      if (vertexLength == 0) continue;
      // A member whose own gather the cluster's light misses under the training lights (near
      // another surface, at a corner) keeps a row of its own.
      const ClusterLight light(maker, clusterRows[c], gradients[2 * c], gradients[2 * c + 1]);
      const uint32_t b = op.memberStart[c];
      for (uint32_t i = b; i < op.memberStart[c + 1]; ++i) {
        const uint32_t v = op.members[i];
        if (uncompressed || light.error(maker, g.raw[i - b], shares.bounce[v], shares.sky[v], st[v]) >
                                kOwnRowError * sideTraining.scale[v])
          vertexRows[v] = maker.make(g.raw[i - b], sides[v].position, vertexLength);
      }
    }
  });
  if (shared) shareRows(op, {vertexRows, clusterRows, gradients});
  storeAll(op, {vertexRows, clusterRows, gradients}, gradientLength > 0, uncompressed);
  if (probes && probes->probeCount() > 0)
    op.probeRows = op::makeProbeRows({scene, lay, op, tree, sky, training, rays}, *probes, s.probeSamples,
                                     s.probeRowLength, uncompressed, probeSh);
  return op;
}

}  // namespace prt::bake
