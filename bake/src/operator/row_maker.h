// A sparse row over the operator's tree cut to a length (prt/bounce_operator.h): leaf entries
// merged into the coarsest nodes that the training lights cannot tell from their leaves. Shared
// by the vertex sides' and clusters' rows (build.cpp) and the probes' rows (probe_rows.cpp).
// Private to the operator's build.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <queue>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bounce_operator.h"
#include "prt/light.h"
#include "training.h"
#include "tree.h"

namespace prt::bake::op {

struct Entry {
  uint32_t leaf;
  float w;
};

// One step of a row's cut (RowMaker::make): the error of the node split into its children (the
// priority it was split at), and the row's length before it.
struct Split {
  float priority;
  uint32_t before;
};

// Sorts entries by leaf and adds up those of one leaf.
inline void mergeEntries(std::vector<Entry>& e) {
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

// A row over the tree from merged leaf entries, cut top-down: from the two roots, each time the
// node whose entry would be wrongest under the training lights (training.h) is split into its
// children, until the row is `maxLength` long or holds only leaves. A node's error is the mean
// over the lights of |Σ its leaves' weight · value − its weight · its value|: what standing for
// its leaves by their mean costs this row. (A row of signed weights, a gradient, is cut alike.)
// Single-child chains are walked down for free. Weight is kept exactly: each entry holds its
// node's whole share.
class RowMaker {
 public:
  static constexpr int K = Training::kLights;
  RowMaker(const BounceOperator& o, const Tree& t, const std::vector<uint8_t>& sky, const Training& tr)
      : op_(o), t_(t), sky_(sky), tr_(tr) {}

  /// `splits` (if given) receives the splits, in order. Splitting also stops at the first
  /// entry whose error is below `above`.
  std::vector<Entry> make(const std::vector<Entry>& leaves, const glm::vec3& x, size_t maxLength,
                          std::vector<Split>* splits = nullptr, float above = -std::numeric_limits<float>::infinity()) {
    if (splits) splits->clear();
    setRow(leaves);
    std::priority_queue<Item> heap;
    for (uint32_t root : {op_.surfaceRoot, op_.skyRoot}) {
      Span s = range(root);
      if (s.hi == s.lo) continue;
      const uint32_t n = descend(root, s);
      heap.push(item(n, s, x));
    }
    std::vector<Entry> done;
    while (!heap.empty()) {
      const Item top = heap.top();
      if (isLeaf(top.node) || top.priority < above || heap.size() + done.size() + 1 > maxLength) break;
      heap.pop();
      if (splits) splits->push_back({top.priority, uint32_t(heap.size() + 1)});
      for (auto [child, span] : split(top.node, top.span)) {
        if (span.hi == span.lo) continue;
        const uint32_t n = descend(child, span);
        heap.push(item(n, span, x));
      }
    }
    for (; !heap.empty(); heap.pop()) done.push_back({heap.top().node, float(weight(heap.top().span))});
    std::sort(done.begin(), done.end(), [](const Entry& a, const Entry& b) { return a.leaf < b.leaf; });
    return done;
  }

  /// Under each training light, what `row` (over the tree) gathers from surfaces and from the
  /// sky apart, each as K values.
  void values(const std::vector<Entry>& row, std::array<double, K>& surface, std::array<double, K>& sky) const {
    surface.fill(0.0), sky.fill(0.0);
    for (const Entry& e : row) {
      const float* v = tr_.of(e.leaf);
      std::array<double, K>& to = sky_[e.leaf] ? sky : surface;
      for (int k = 0; k < K; ++k) to[size_t(k)] += double(e.w) * v[k];
    }
  }

 private:
  // The entries [lo, hi) of the row under a node (its leaves are one interval of leaf indices,
  // and the row ascends by leaf).
  struct Span {
    uint32_t lo = 0, hi = 0;
  };
  struct Item {
    float priority;
    uint32_t node;
    Span span;
    bool operator<(const Item& o) const { return priority < o.priority || (priority == o.priority && node > o.node); }
  };
  void setRow(const std::vector<Entry>& leaves) {
    e_ = &leaves;
    prefix_.assign((leaves.size() + 1) * (K + 1), 0.0);
    for (size_t i = 0; i < leaves.size(); ++i) {
      const double* p = &prefix_[i * (K + 1)];
      double* q = &prefix_[(i + 1) * (K + 1)];
      const float* v = tr_.of(leaves[i].leaf);
      q[0] = p[0] + double(leaves[i].w);
      for (int k = 0; k < K; ++k) q[k + 1] = p[k + 1] + double(leaves[i].w) * v[k];
    }
  }
  bool isLeaf(uint32_t n) const { return n < op_.leaves(); }
  // The first entry in [lo, hi) whose leaf is at least `leaf`.
  uint32_t lowerBound(uint32_t lo, uint32_t hi, uint32_t leaf) const {
    const auto b = e_->begin();
    return uint32_t(std::lower_bound(b + lo, b + hi, leaf, [](const Entry& a, uint32_t v) { return a.leaf < v; }) - b);
  }
  Span range(uint32_t n) const {
    const uint32_t lo = lowerBound(0, uint32_t(e_->size()), t_.leafLo[n]);
    return {lo, lowerBound(lo, uint32_t(e_->size()), t_.leafHi[n])};
  }
  // The spans of n's two children from n's: the children split n's leaf interval in two, so
  // one search within n's span finds where the upper child's entries begin.
  std::array<std::pair<uint32_t, Span>, 2> split(uint32_t n, Span s) const {
    const uint32_t* ch = &op_.children[2 * (n - op_.leaves())];
    const int upper = t_.leafLo[ch[0]] < t_.leafLo[ch[1]] ? 1 : 0;
    const uint32_t m = lowerBound(s.lo, s.hi, t_.leafLo[ch[upper]]);
    std::array<std::pair<uint32_t, Span>, 2> out;
    out[size_t(upper)] = {ch[upper], Span{m, s.hi}};
    out[size_t(1 - upper)] = {ch[1 - upper], Span{s.lo, m}};
    return out;
  }
  double weight(Span s) const { return prefix_[s.hi * (K + 1)] - prefix_[s.lo * (K + 1)]; }
  // Down a chain of nodes with one child in the row, to the first with two (or a leaf); `s`
  // becomes that node's span (the same entries).
  uint32_t descend(uint32_t n, Span& s) const {
    while (!isLeaf(n)) {
      const auto parts = split(n, s);
      const bool a = parts[0].second.hi > parts[0].second.lo, b = parts[1].second.hi > parts[1].second.lo;
      if (a && b) break;
      n = a ? parts[0].first : parts[1].first;
    }
    return n;
  }
  // A node's error under the training lights; a geometric term a thousand times smaller
  // (mergeRisk: its angular size and normal spread, per unit of weight) orders the nodes that
  // no training light tells apart.
  Item item(uint32_t n, Span s, const glm::vec3& x) const {
    if (isLeaf(n)) return {-1.0f, n, s};
    const double* p = &prefix_[s.lo * (K + 1)];
    const double* q = &prefix_[s.hi * (K + 1)];
    const double w = q[0] - p[0];
    const float* v = tr_.of(n);
    double err = 0.0;
    for (int k = 0; k < K; ++k) err += std::fabs(q[k + 1] - p[k + 1] - w * double(v[k]));
    return {float(err / K + 1e-3 * std::fabs(w) * double(mergeRisk(t_, n, sky_[n] != 0, x))), n, s};
  }

  const BounceOperator& op_;
  const Tree& t_;
  const std::vector<uint8_t>& sky_;
  const Training& tr_;
  const std::vector<Entry>* e_ = nullptr;
  std::vector<double> prefix_;  // per row entry i: Σ_{j<i} w_j, then Σ_{j<i} w_j · value_k(j) for each light k
};

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

}  // namespace prt::bake::op
