// A sparse row over the operator's tree cut to a length (prt/bounce_operator.h): leaf entries
// merged into the coarsest nodes that the training lights cannot tell from their leaves. Shared
// by the vertex sides' and clusters' rows (build.cpp) and the probes' rows (probe_rows.cpp).
// Private to the operator's build.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
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

  std::vector<Entry> make(const std::vector<Entry>& leaves, const glm::vec3& x, size_t maxLength) {
    setRow(leaves);
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
  struct Item {
    float priority;
    uint32_t node;
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
    return prefix_[b * (K + 1)] - prefix_[a * (K + 1)];
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
  // A node's error under the training lights; a geometric term a thousand times smaller
  // (mergeRisk: its angular size and normal spread, per unit of weight) orders the nodes that
  // no training light tells apart.
  Item item(uint32_t n, const glm::vec3& x) const {
    if (isLeaf(n)) return {-1.0f, n};
    const auto [a, b] = range(n);
    const double* p = &prefix_[a * (K + 1)];
    const double* q = &prefix_[b * (K + 1)];
    const double w = q[0] - p[0];
    const float* v = tr_.of(n);
    double err = 0.0;
    for (int k = 0; k < K; ++k) err += std::fabs(q[k + 1] - p[k + 1] - w * double(v[k]));
    return {float(err / K + 1e-3 * std::fabs(w) * double(mergeRisk(t_, n, sky_[n] != 0, x))), n};
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
