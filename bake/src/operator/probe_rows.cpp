// The probes' rows of the bounce operator (probe_rows.h): a probe's own rays as the probe bake
// casts them (probe/directions.cpp), each ray's share of the clusters at its hit (barycentric,
// at the hit's three vertex sides) or of the sky bins it escapes through (bilinear), summed per
// leaf with the SH of its direction; the row cut as a vertex row is (RowMaker), and each kept
// node's rays stored as their share and the mean SH of their directions.
#include "probe_rows.h"

#include <algorithm>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../probe/probe_types.h"
#include "../surface_layout.h"
#include "prt/error.h"
#include "prt/math.h"
#include "prt/sh.h"
#include "row_maker.h"

namespace prt::bake {

namespace {

uint32_t latticeIndex(const ProbeGrid& g, const glm::ivec3& c) {
  return uint32_t(size_t(c.x) + size_t(g.dims.x) * (size_t(c.y) + size_t(g.dims.y) * size_t(c.z)));
}

// The grid's probes in ascending lattice order (the order of the stored rows).
std::vector<uint32_t> probesByLattice(const ProbeGrid& g) {
  std::vector<uint32_t> order(g.probeCount());
  for (uint32_t p = 0; p < order.size(); ++p) order[p] = p;
  std::sort(order.begin(), order.end(),
            [&](uint32_t a, uint32_t b) { return latticeIndex(g, g.coord[a]) < latticeIndex(g, g.coord[b]); });
  return order;
}

// b_l = √((2l + 1)/4π): |y_lm| ≤ b_l (the addition theorem: Σ_m y_lm² = b_l²).
double bandBound(int l) { return std::sqrt((2.0 * l + 1.0) / (4.0 * kPi)); }

}  // namespace

namespace op {

namespace {

// One ray's share of one leaf.
struct RayShare {
  uint32_t leaf, ray;
  float w;
};

// One probe's row in the making: its leaves (scalar shares, for RowMaker), and per leaf the sum
// of its rays' shares times their direction and times their SH.
struct ProbeGather {
  const ProbeRowInputs& in;
  const probe::ProbeKernels kernels = probe::ProbeKernels::active();
  uint64_t seed;
  uint32_t K;
  int n2;

  std::vector<RayShare> shares;
  std::vector<glm::vec3> dirs;
  std::vector<double> ys;
  std::vector<Entry> leaves;
  std::vector<double> leafSh;

  // The rays from x of the probe bake's stream `stream`, as the probe bake traces them.
  void trace(const glm::vec3& x, uint64_t stream) {
    shares.clear();
    dirs.resize(K);
    const probe::SphereSet set(seed, stream, kernels.directions);
    constexpr uint32_t kBatch = 256;
    alignas(64) Ray batch[kBatch];
    const float w = 1.0f / float(K);
    for (uint32_t first = 0; first < K; first += kBatch) {
      const uint32_t count = std::min(kBatch, K - first);
      set.fill(batch, x, first, count);
      in.rays.intersect(batch, count);
      for (uint32_t j = 0; j < count; ++j) {
        const Ray& r = batch[j];
        const uint32_t ray = first + j;
        dirs[ray] = r.dir;
        if (!r.hit()) {
          splatSky(r.dir, in.op.skyWidth, in.op.skyHeight, [&](uint32_t bin, float s) {
            shares.push_back({in.tree.skyLeafOfBin[bin], ray, w * s});
          });
          continue;
        }
        if (in.lay.vertexOffset[r.mesh] == SIZE_MAX) continue;
        const uint32_t tri = recordedTriangle(in.lay, r);
        if (tri == Layout::kNone) continue;
        const uint32_t* tv = &in.lay.triVerts[3 * size_t(tri)];
        shares.push_back({in.tree.clusterOf[tv[0]], ray, w * (1.0f - r.u - r.v)});
        shares.push_back({in.tree.clusterOf[tv[1]], ray, w * r.u});
        shares.push_back({in.tree.clusterOf[tv[2]], ray, w * r.v});
      }
    }
  }

  // The shares summed per leaf, in leaf order then ray order (whatever the thread).
  void sumLeaves(int bands) {
    std::sort(shares.begin(), shares.end(), [](const RayShare& a, const RayShare& b) {
      return a.leaf < b.leaf || (a.leaf == b.leaf && a.ray < b.ray);
    });
    ys.resize(size_t(K) * n2);
    for (uint32_t j = 0; j < K; ++j) sh::evaluate(bands, glm::dvec3(dirs[j]), &ys[size_t(j) * n2]);
    leaves.clear(), leafSh.clear();
    double w = 0.0;
    for (size_t i = 0; i < shares.size(); ++i) {
      const RayShare& s = shares[i];
      if (i == 0 || s.leaf != shares[i - 1].leaf) {
        if (i > 0) leaves.back().w = float(w);
        leaves.push_back({s.leaf, 0.0f});
        leafSh.resize(leafSh.size() + size_t(n2), 0.0);
        w = 0.0;
      }
      w += double(s.w);
      double* y = &leafSh[leafSh.size() - size_t(n2)];
      for (int j = 0; j < n2; ++j) y[j] += double(s.w) * ys[size_t(s.ray) * n2 + size_t(j)];
    }
    if (!leaves.empty()) leaves.back().w = float(w);
  }
};

// One probe's row: per kept node, its rays' share and SH sums.
struct MadeRow {
  std::vector<uint32_t> node;
  std::vector<double> w;
  std::vector<float> sh;
};

void keep(const ProbeGather& g, const Tree& tree, const std::vector<Entry>& cut, MadeRow& out) {
  const int n2 = g.n2;
  for (const Entry& e : cut) {
    auto lo = std::lower_bound(g.leaves.begin(), g.leaves.end(), tree.leafLo[e.leaf],
                               [](const Entry& a, uint32_t v) { return a.leaf < v; });
    double w = 0.0;
    std::vector<double> y(size_t(n2), 0.0);
    for (auto it = lo; it != g.leaves.end() && it->leaf < tree.leafHi[e.leaf]; ++it) {
      const size_t i = size_t(it - g.leaves.begin());
      w += double(it->w);
      for (int j = 0; j < n2; ++j) y[size_t(j)] += g.leafSh[i * size_t(n2) + size_t(j)];
    }
    out.node.push_back(e.leaf);
    out.w.push_back(w);
    for (int j = 0; j < n2; ++j) out.sh.push_back(float(y[size_t(j)]));
  }
}

// A probe's row as the operator holds it: weights on the one-byte codes' values with the row's
// sum kept unless `exact` (an uncompressed operator, never stored; build.cpp's storeRows), and
// each entry's mean SH as bytes.
struct HeldRow {
  std::vector<uint32_t> node;
  std::vector<uint16_t> weight;
  std::vector<int8_t> shape;
};
HeldRow held(const MadeRow& r, int bands, bool exact) {
  const size_t n2 = size_t(bands) * size_t(bands);
  std::vector<double> scaled(r.node.size());
  for (size_t e = 0; e < r.node.size(); ++e) scaled[e] = r.w[e] * BounceOperator::kWeightOne;
  const std::vector<uint16_t> weights = BounceOperator::storedWeights(scaled, exact);
  HeldRow out;
  for (size_t e = 0; e < r.node.size(); ++e) {
    if (weights[e] == 0) continue;
    out.node.push_back(r.node[e]);
    out.weight.push_back(weights[e]);
    for (int l = 1; l < bands; ++l)
      for (int j = l * l; j < (l + 1) * (l + 1); ++j) {
        const double mean = double(r.sh[e * n2 + size_t(j)]) / r.w[e] / bandBound(l);
        const long v = std::lround(mean * BounceOperator::ProbeRows::kShapeOne);
        out.shape.push_back(int8_t(std::clamp<long>(v, -127, 127)));
      }
  }
  return out;
}

// Appends a held row to the operator's rows, and frees it.
void append(BounceOperator::ProbeRows& rows, HeldRow& r) {
  rows.rows.node.insert(rows.rows.node.end(), r.node.begin(), r.node.end());
  rows.rows.weight.insert(rows.rows.weight.end(), r.weight.begin(), r.weight.end());
  rows.shape.insert(rows.shape.end(), r.shape.begin(), r.shape.end());
  rows.rows.start.push_back(uint32_t(rows.rows.node.size()));
  r = HeldRow{};
}

}  // namespace

BounceOperator::ProbeRows makeProbeRows(const ProbeRowInputs& in, const ProbeGrid& grid, int samples, int rowLength,
                                        bool uncompressed, ProbeShRows* full) {
  BounceOperator::ProbeRows rows;
  rows.bands = grid.bands;
  rows.samples = std::min(samples, grid.info.samples > 0 ? grid.info.samples : samples);
  rows.rowLength = rowLength;
  rows.dims = grid.dims, rows.origin = grid.origin, rows.spacing = grid.spacing, rows.seed = grid.info.seed;
  const int n2 = grid.coeffs();
  // Each probe's row is held as it will be stored as soon as it is made (its SH as floats only
  // where `full` asks for them): a grid of 30k probes would hold 140 MB of float rows otherwise.
  std::vector<MadeRow> made(full ? grid.probeCount() : 0);
  std::vector<HeldRow> kept(grid.probeCount());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, grid.probeCount(), 4), [&](const tbb::blocked_range<size_t>& r) {
    RowMaker maker(in.op, in.tree, in.sky, in.training);
    ProbeGather g{in, probe::ProbeKernels::active(), grid.info.seed, uint32_t(rows.samples), n2};
    MadeRow one;
    for (size_t p = r.begin(); p != r.end(); ++p) {
      if (!(grid.validity[p] > 0.0f)) continue;
      const glm::vec3 x(grid.position(p));
      g.trace(x, 2 * uint64_t(latticeIndex(grid, grid.coord[p])) + 1);
      g.sumLeaves(grid.bands);
      MadeRow& m = full ? made[p] : one;
      m = MadeRow{};
      if (uncompressed)
        keep(g, in.tree, g.leaves, m);
      else
        keep(g, in.tree, maker.make(g.leaves, x, size_t(rowLength)), m);
      kept[p] = held(m, grid.bands, uncompressed);
    }
  });
  rows.rows.start.assign(1, 0);
  for (uint32_t p : probesByLattice(grid)) {
    rows.lattice.push_back(latticeIndex(grid, grid.coord[p]));
    append(rows, kept[p]);
  }
  if (full) {
    full->bands = grid.bands;
    full->start.assign(1, 0);
    full->node.clear(), full->sh.clear();
    for (const MadeRow& m : made) {
      full->node.insert(full->node.end(), m.node.begin(), m.node.end());
      full->sh.insert(full->sh.end(), m.sh.begin(), m.sh.end());
      full->start.push_back(uint32_t(full->node.size()));
    }
  }
  return rows;
}

}  // namespace op

void checkProbeRows(const BounceOperator& op, const ProbeGrid& grid, const std::string& where) {
  if (!op.probeRows.present()) throw Error(cat(where, ": probe rows: none (the scene was baked without probes)"));
  std::vector<uint32_t> lattice;
  for (uint32_t p : probesByLattice(grid)) lattice.push_back(latticeIndex(grid, grid.coord[p]));
  checkProbeRows(op, grid.dims, grid.origin, grid.spacing, grid.info.seed, lattice, where);
}

void addProbeBounce(const BounceOperator& op, const ProbeGrid& grid, const std::vector<glm::vec3>& values,
                    std::vector<glm::vec3>& relit) {
  const BounceOperator::ProbeRows& pr = op.probeRows;
  const int n2 = grid.coeffs();
  PRT_CHECK_EQ(relit.size(), grid.probeCount() * size_t(n2));
  PRT_CHECK_EQ(values.size(), op.nodes());
  PRT_CHECK_EQ(pr.bands, grid.bands);
  // Per coefficient, what a stored shape value stands for: ȳ_j = shape · b_l / kShapeOne.
  std::vector<float> scale(size_t(n2), 0.0f);
  for (int l = 1; l < grid.bands; ++l)
    for (int j = l * l; j < (l + 1) * (l + 1); ++j)
      scale[size_t(j)] = float(bandBound(l) / BounceOperator::ProbeRows::kShapeOne);
  const float y0 = float(bandBound(0)), unit = 4.0f / float(BounceOperator::kWeightOne);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, grid.probeCount(), 16), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t p = r.begin(); p != r.end(); ++p) {
      const uint32_t idx = latticeIndex(grid, grid.coord[p]);
      const auto it = std::lower_bound(pr.lattice.begin(), pr.lattice.end(), idx);
      PRT_CHECK(it != pr.lattice.end() && *it == idx);
      const size_t row = size_t(it - pr.lattice.begin());
      glm::vec3* c = &relit[p * size_t(n2)];
      for (uint32_t e = pr.rows.start[row]; e < pr.rows.start[row + 1]; ++e) {
        const glm::vec3 v = float(pr.rows.weight[e]) * unit * values[pr.rows.node[e]];
        const int8_t* shape = &pr.shape[size_t(e) * (size_t(n2) - 1)];
        c[0] += y0 * v;
        for (int j = 1; j < n2; ++j) c[j] += float(shape[j - 1]) * scale[size_t(j)] * v;
      }
    }
  });
}

void addProbeBounce(const ProbeShRows& rows, const ProbeGrid& grid, const std::vector<glm::vec3>& values,
                    std::vector<glm::vec3>& relit) {
  const int n2 = grid.coeffs();
  PRT_CHECK_EQ(rows.bands, grid.bands);
  PRT_CHECK_EQ(rows.start.size(), grid.probeCount() + 1);
  PRT_CHECK_EQ(relit.size(), grid.probeCount() * size_t(n2));
  for (size_t p = 0; p < grid.probeCount(); ++p)
    for (uint32_t e = rows.start[p]; e < rows.start[p + 1]; ++e)
      for (int j = 0; j < n2; ++j)
        relit[p * size_t(n2) + size_t(j)] += 4.0f * rows.sh[size_t(e) * n2 + size_t(j)] * values[rows.node[e]];
}

}  // namespace prt::bake
