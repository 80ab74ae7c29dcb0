// Building the bounce operator (prt/bake/bounce_operator.h): the clusters and trees (tree.cpp),
// then every vertex side's gather rays, traced once, each row compressed as soon as it is made
// so that no hit record outlives its vertex.
#include <algorithm>
#include <cmath>
#include <queue>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../stage_runner.h"
#include "../surface_layout.h"
#include "../vertex_rays.h"
#include "prt/bake/bounce_operator.h"
#include "prt/error.h"
#include "prt/light.h"
#include "tree.h"

namespace prt::bake {

void validate(const OperatorSettings& s) {
  auto within = [](const char* what, int v, int lo, int hi) {
    if (v < lo || v > hi) throw Error(cat(what, " ", v, ": must be between ", lo, " and ", hi));
  };
  within("operator samples", s.samples, 1, 16777216);
  within("operator cluster size", s.clusterSize, 1, 65536);
  within("operator row length", s.rowLength, 0, BounceOperator::kMaxRowLength);
  within("operator cluster row length", s.clusterRowLength, 1, BounceOperator::kMaxRowLength);
  within("operator sky bins across", s.skyWidth, 1, 1024);
  within("operator sky bins down", s.skyHeight, 1, 1024);
  within("operator sample points", s.samplePoints, 1, 64);
  if (s.threads < 0) throw Error(cat("threads ", s.threads, ": must be 0 (all cores) or more"));
}

namespace {

using op::Tree;

struct Entry {
  uint32_t leaf;
  float w;
};

// Sorts entries by leaf and adds up those of one leaf.
void mergeEntries(std::vector<Entry>& e) {
  std::sort(e.begin(), e.end(), [](const Entry& a, const Entry& b) { return a.leaf < b.leaf; });
  size_t out = 0;
  for (size_t i = 0; i < e.size(); ++i) {
    if (out > 0 && e[out - 1].leaf == e[i].leaf)
      e[out - 1].w += e[i].w;
    else
      e[out++] = e[i];
  }
  e.resize(out);
}

// A row over the tree from merged leaf entries: top-down from the two roots, each time the
// node whose weight times angular size (what merging below it risks) is largest is split into
// its children, until the row is `maxLength` long or holds only leaves. Single-child chains
// are walked down for free. Weight is kept exactly: each entry holds its node's whole share.
class RowMaker {
 public:
  RowMaker(const BounceOperator& o, const Tree& t, const std::vector<uint8_t>& sky) : op_(o), t_(t), sky_(sky) {}

  std::vector<Entry> make(const std::vector<Entry>& leaves, const glm::vec3& x, size_t maxLength) {
    e_ = &leaves;
    prefix_.assign(leaves.size() + 1, 0.0);
    for (size_t i = 0; i < leaves.size(); ++i) prefix_[i + 1] = prefix_[i] + double(leaves[i].w);
    std::priority_queue<Item> heap;
    for (uint32_t root : {op_.surfaceRoot, op_.skyRoot})
      if (count(root) > 0) heap.push(item(descend(root), x));
    std::vector<Entry> done;
    while (!heap.empty()) {
      const Item top = heap.top();
      if (isLeaf(top.node) || heap.size() + done.size() + 1 > maxLength) break;
      heap.pop();
      const uint32_t* ch = &op_.children[2 * (top.node - op_.leaves())];
      for (int k = 0; k < 2; ++k)
        if (count(ch[k]) > 0) heap.push(item(descend(ch[k]), x));
    }
    for (; !heap.empty(); heap.pop()) done.push_back({heap.top().node, float(weight(heap.top().node))});
    std::sort(done.begin(), done.end(), [](const Entry& a, const Entry& b) { return a.leaf < b.leaf; });
    return done;
  }

 private:
  struct Item {
    float priority;
    uint32_t node;
    bool operator<(const Item& o) const { return priority < o.priority || (priority == o.priority && node > o.node); }
  };
  bool isLeaf(uint32_t n) const { return n < op_.leaves(); }
  std::pair<size_t, size_t> range(uint32_t n) const {
    auto lo =
        std::lower_bound(e_->begin(), e_->end(), t_.leafLo[n], [](const Entry& a, uint32_t v) { return a.leaf < v; });
    auto hi = std::lower_bound(lo, e_->end(), t_.leafHi[n], [](const Entry& a, uint32_t v) { return a.leaf < v; });
    return {size_t(lo - e_->begin()), size_t(hi - e_->begin())};
  }
  size_t count(uint32_t n) const {
    const auto [a, b] = range(n);
    return b - a;
  }
  double weight(uint32_t n) const {
    const auto [a, b] = range(n);
    return prefix_[b] - prefix_[a];
  }
  uint32_t descend(uint32_t n) const {
    while (!isLeaf(n)) {
      const uint32_t* ch = &op_.children[2 * (n - op_.leaves())];
      const bool a = count(ch[0]) > 0, b = count(ch[1]) > 0;
      if (a && b) break;
      n = a ? ch[0] : ch[1];
    }
    return n;
  }
  // A node's risk, per unit of its weight: mergeRisk, plus the evidence that the row does not
  // see all of it. Were its m leaves all in view, the K·w rays that reached it would have
  // touched a share of about 1 − exp(−K·w/m) of them; a row that touched far fewer (the two
  // sides of a slab, a wall behind another) would average light it cannot see.
  Item item(uint32_t n, const glm::vec3& x) const {
    if (isLeaf(n)) return {-1.0f, n};
    const double w = weight(n);
    const double m = double(t_.leafHi[n] - t_.leafLo[n]);
    const double expected = 1.0 - std::exp(-double(op_.samples) * w / m);
    const double unseen = std::max(0.0, expected - double(count(n)) / m);
    return {float(w * (double(op::mergeRisk(t_, n, sky_[n] != 0, x)) + unseen)), n};
  }

  const BounceOperator& op_;
  const Tree& t_;
  const std::vector<uint8_t>& sky_;
  const std::vector<Entry>* e_ = nullptr;
  std::vector<double> prefix_;
};

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

// The bilinear share of direction d among the four sky bins around it (wrapping across u).
template <class Add>
void splatSky(const glm::vec3& d, int W, int H, Add&& add) {
  const glm::dvec2 uv = equirectUv(glm::dvec3(d));
  const double x = uv.x * W - 0.5, y = std::clamp(uv.y * H - 0.5, 0.0, double(H - 1));
  const int x0 = int(std::floor(x)), y0 = std::min(int(std::floor(y)), H - 1);
  const float fx = float(x - x0), fy = float(y - y0);
  const int y1 = std::min(y0 + 1, H - 1);
  const int xa = ((x0 % W) + W) % W, xb = (xa + 1) % W;
  add(uint32_t(y0 * W + xa), (1 - fx) * (1 - fy));
  add(uint32_t(y0 * W + xb), fx * (1 - fy));
  add(uint32_t(y1 * W + xa), (1 - fx) * fy);
  add(uint32_t(y1 * W + xb), fx * fy);
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

  // Vertex side v's gather: its K rays' shares of clusters (barycentric, at the hit's three
  // vertex sides) and of sky bins (bilinear), each ray 1/K. A ray that hits the back of a
  // one-sided face sends nothing.
  void gather(size_t v, std::vector<Entry>& out) const {
    out.clear();
    const VertexSampler sampler(origins[v], normalOf(scene, lay, v), seed, v, tnear);
    const float w = 1.0f / float(K);
    traceGatherRays(
        rays, lay, sampler, K,
        [&](uint32_t, const Ray& r) {
          splatSky(r.dir, op.skyWidth, op.skyHeight, [&](uint32_t bin, float share) {
            out.push_back({tree.skyLeafOfBin[bin], w * share});
          });
        },
        [&](uint32_t tri, uint16_t q1, uint16_t q2) {
          const float b1 = q1 / 65535.0f, b2 = q2 / 65535.0f;
          const uint32_t* tv = &lay.triVerts[3 * size_t(tri)];
          out.push_back({tree.clusterOf[tv[0]], w * (1.0f - b1 - b2)});
          out.push_back({tree.clusterOf[tv[1]], w * b1});
          out.push_back({tree.clusterOf[tv[2]], w * b2});
        });
    mergeEntries(out);
  }
};

// The resolution at which a vertex's view is compared with its cluster's, and how different it
// must be to keep a row of its own. Two gathers of 256 rays of one view differ by a total
// variation of about 0.1 over 16 nodes (Σ √(p/K) · √(2/π) / 2), so 0.25 is a real difference: a
// different near field.
constexpr size_t kCompareLength = 16;
constexpr double kOwnRowDivergence = 0.25;

// The total variation distance between a vertex's gather (leaf entries) and a row over the
// tree: ½ Σ over the row's nodes of |the vertex's weight below the node − the row's|, the
// vertex's weight outside every node counted whole.
double divergence(const std::vector<Entry>& leaves, const std::vector<Entry>& row, const Tree& t) {
  struct Range {
    uint32_t lo, hi;
    double row, mine;
  };
  std::vector<Range> ranges;
  for (const Entry& e : row) ranges.push_back({t.leafLo[e.leaf], t.leafHi[e.leaf], e.w, 0.0});
  std::sort(ranges.begin(), ranges.end(), [](const Range& a, const Range& b) { return a.lo < b.lo; });
  double outside = 0.0;
  for (const Entry& x : leaves) {
    auto it =
        std::upper_bound(ranges.begin(), ranges.end(), x.leaf, [](uint32_t v, const Range& r) { return v < r.lo; });
    if (it != ranges.begin() && x.leaf < (it - 1)->hi)
      (it - 1)->mine += x.w;
    else
      outside += x.w;
  }
  double d = outside;
  for (const Range& r : ranges) d += std::fabs(r.mine - r.row);
  return 0.5 * d;
}

void storeRows(BounceOperator::Rows& rows, const std::vector<std::vector<Entry>>& made) {
  rows.start.assign(1, 0);
  rows.node.clear(), rows.weight.clear();
  for (const std::vector<Entry>& row : made) {
    for (const Entry& e : row) {
      const long q = std::lround(double(e.w) * BounceOperator::kWeightOne);
      if (q <= 0) continue;
      rows.node.push_back(e.leaf);
      rows.weight.push_back(uint16_t(std::min<long>(q, BounceOperator::kWeightOne)));
    }
    rows.start.push_back(uint32_t(rows.node.size()));
  }
}

}  // namespace

BounceOperator buildBounceOperator(const Scene& scene, const OperatorSettings& s, int bounces, uint64_t seed,
                                   bool uncompressed) {
  validate(s);
  const ThreadLimit threadLimit(s.threads);
  const Layout lay = makeLayout(scene);
  if (lay.vertices == 0) throw Error("bounce operator: the scene has no baked vertices");
  BounceOperator op;
  op.samples = s.samples, op.bounces = bounces, op.seed = seed;
  op.clusterSize = s.clusterSize, op.rowLength = s.rowLength, op.clusterRowLength = s.clusterRowLength;
  op.skyWidth = s.skyWidth, op.skyHeight = s.skyHeight, op.samplePoints = s.samplePoints;
  op.vertexSides = uint32_t(lay.vertices);
  const std::vector<op::SidePoint> sides = sidePoints(scene, lay);
  const Tree tree = op::buildTree(op, sides);
  const std::vector<uint8_t> sky = skyNodeMask(op);
  const RayScene rays(scene);
  const std::vector<glm::vec3> origins = rayOrigins(scene, lay, rays.sceneExtent());
  const Trace trace{scene, lay, tree, op, rays, origins, tnearFor(rays.sceneExtent()), seed, uint32_t(s.samples)};
  const size_t vertexLength = uncompressed ? SIZE_MAX : size_t(s.rowLength);
  const size_t clusterLength = uncompressed ? SIZE_MAX : size_t(s.clusterRowLength);
  std::vector<std::vector<Entry>> vertexRows(lay.vertices), clusterRows(op.clusters);
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, op.clusters, 4), [&](const tbb::blocked_range<uint32_t>& r) {
    RowMaker maker(op, tree, sky);
    std::vector<std::vector<Entry>> raw;
    std::vector<Entry> all;
    for (uint32_t c = r.begin(); c != r.end(); ++c) {
      all.clear();
      const uint32_t b = op.memberStart[c], e = op.memberStart[c + 1];
      const float area = op.leafWeight[c];
      raw.resize(std::max<size_t>(raw.size(), e - b));
      for (uint32_t i = b; i < e; ++i) {
        const uint32_t v = op.members[i];
        trace.gather(v, raw[i - b]);
        // The cluster's gather: its members' area-weighted mean (the plain mean without area).
        const float share = area > 1e-30f ? sides[v].area / area : 1.0f / float(e - b);
        for (const Entry& x : raw[i - b]) all.push_back({x.leaf, x.w * share});
      }
      mergeEntries(all);
      clusterRows[c] = maker.make(all, tree.center[c], clusterLength);
      if (vertexLength == 0) continue;
      // A member whose own view differs from its cluster's (near another surface, at a corner)
      // keeps a row of its own; the others take the cluster's light.
      const std::vector<Entry> coarse = maker.make(all, tree.center[c], kCompareLength);
      for (uint32_t i = b; i < e; ++i)
        if (uncompressed || divergence(raw[i - b], coarse, tree) > kOwnRowDivergence)
          vertexRows[op.members[i]] = maker.make(raw[i - b], sides[op.members[i]].position, vertexLength);
    }
  });
  storeRows(op.vertexRows, vertexRows);
  storeRows(op.clusterRows, clusterRows);
  return op;
}

}  // namespace prt::bake
