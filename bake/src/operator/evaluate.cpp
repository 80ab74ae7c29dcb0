// The bounce operator at a light change (prt/bake/bounce_operator.h): sky bins, the direct
// light at the clusters, the bounces cluster to cluster, then one sparse row per vertex side.
#include <algorithm>
#include <chrono>
#include <optional>
#include <span>

#include <immintrin.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../sky_prefilter.h"
#include "../stage_runner.h"
#include "../surface_layout.h"
#include "prt/bake/bounce_operator.h"
#include "prt/error.h"
#include "prt/light.h"
#include "prt/math.h"
#include "training.h"
#include "tree.h"

namespace prt::bake {

namespace {

constexpr float kUnit = 1.0f / float(BounceOperator::kWeightOne);

// A node's light as 4 floats (RGB and a zero), so that a row's product is one load and one
// multiply-add an entry.
struct Light4 {
  __m128 v;
};
using Lights4 = std::vector<Light4>;
const Light4 kDark{_mm_setzero_ps()};

inline Light4 light4(const glm::vec3& c) { return {_mm_setr_ps(c.r, c.g, c.b, 0.0f)}; }
inline glm::vec3 rgb(__m128 v) {
  alignas(16) float f[4];
  _mm_store_ps(f, v);
  return {f[0], f[1], f[2]};
}

// Σ w · value over entries [b, e) of rows whose nodes are `nodes` and weights `w` (held as
// floats in the rows' weight units), two sums in turn, so that each multiply-add waits on the
// one before the last.
inline glm::vec3 range(const std::vector<uint32_t>& nodes, const std::vector<float>& w, uint32_t b, uint32_t e,
                       const Lights4& value) {
  __m128 a = _mm_setzero_ps(), c = _mm_setzero_ps();
  const uint32_t* node = nodes.data();
  const float* weight = w.data();
  uint32_t i = b;
  for (; i + 1 < e; i += 2) {
    a = _mm_add_ps(a, _mm_mul_ps(_mm_set1_ps(weight[i]), value[node[i]].v));
    c = _mm_add_ps(c, _mm_mul_ps(_mm_set1_ps(weight[i + 1]), value[node[i + 1]].v));
  }
  if (i < e) a = _mm_add_ps(a, _mm_mul_ps(_mm_set1_ps(weight[i]), value[node[i]].v));
  return rgb(_mm_add_ps(a, c));
}

}  // namespace

struct OperatorLighting::Impl {
  const Scene& scene;
  const BounceOperator& op;
  Layout lay;
  int threads;
  std::optional<RayScene> rays;
  std::vector<uint8_t> sky;       // per node: in the sky tree
  std::vector<float> nodeWeight;  // per node: area or solid angle below it
  std::vector<float> childShare;  // per inner node i: its children's shares of its weight, 2i and 2i + 1
  std::vector<float> vertexW, clusterW, gradientW;  // the rows' weights as floats, in their units
  int binBands = 0;                                 // binPoints' bands (0: not yet made)
  std::vector<glm::dvec3> binDir;
  std::vector<double> binY;
  // The clusters' sample points, rank by rank: the first point of every cluster, then the second
  // of those that have two, ... (rankStart[r] .. rankStart[r + 1] are the points of rank r), so
  // that the first n points of every cluster are one prefix.
  std::vector<glm::vec3> points, normals;
  std::vector<uint32_t> rankStart, pointCluster, pointSide, pointCount, pointRank;
  std::vector<float> pointShare;  // pointShares
  int directN2 = 0;
  std::vector<float> memberShare, areaDirect, pointDirect;  // meanDirectTransfers
  std::vector<uint32_t> clusterOf;
  // Per cluster row: where its sky leaves begin and where its inner nodes begin (a row ascends
  // by node: surface leaves, sky leaves, inner nodes of either tree).
  std::vector<uint32_t> rowSky, rowInner, gradientSkyAt, gradientInnerAt;
  std::vector<glm::vec3> clusterBounce, clusterSky;  // what a cluster gathers from surfaces, from the sky
  // Per vertex side: how much more of the bounced light and of the sky it gets than its
  // cluster's mean, by its own transfer (below).
  std::vector<float> bounceShare, skyShare;
  std::vector<float> area;  // per vertex side, for a cluster's mean of its members' light
  // Per vertex side: its place in its cluster's frame (op::clusterCoordinates), and per
  // cluster gradient row what it gathers from surfaces and from the sky.
  std::vector<glm::vec2> st;
  std::vector<glm::vec3> gradientBounce, gradientSky;

  PrefilteredSky filtered;
  Lights4 skyValue, bounced, next, total;  // per node
  std::vector<glm::vec3> clusterE0;
  OperatorTimes times;

  Impl(const Scene& s, const BounceOperator& o, bool traceShadows, int t)
      : scene(s), op(o), lay(makeLayout(s)), threads(t), sky(skyNodeMask(o)), filtered(uint32_t(o.samples)) {
    PRT_CHECK_EQ(lay.vertices, size_t(op.vertexSides));
    nodeWeight = nodeWeights(op);
    area = op::sideAreas(s, lay);
    clusterOf.assign(op.vertexSides, 0);
    for (uint32_t c = 0; c < op.clusters; ++c)
      for (uint32_t i = op.memberStart[c]; i < op.memberStart[c + 1]; ++i) clusterOf[op.members[i]] = c;
    const op::TransferShares sh = op::transferShares(s, lay, o, area);
    bounceShare = sh.bounce, skyShare = sh.sky;
    if (!o.clusterGradients.start.empty()) st = op::clusterCoordinates(s, lay, o, area);
    splitRows(op.clusterRows, rowSky, rowInner);
    vertexW.assign(op.vertexRows.weight.begin(), op.vertexRows.weight.end());
    clusterW.assign(op.clusterRows.weight.begin(), op.clusterRows.weight.end());
    gradientW.assign(op.clusterGradients.weight.begin(), op.clusterGradients.weight.end());
    childShare.resize(op.children.size());
    for (size_t i = 0; i < op.children.size() / 2; ++i) {
      const size_t n = op.leaves() + i;
      childShare[2 * i] = nodeWeight[op.children[2 * i]] / nodeWeight[n];
      childShare[2 * i + 1] = nodeWeight[op.children[2 * i + 1]] / nodeWeight[n];
    }
    splitRows(op.clusterGradients, gradientSkyAt, gradientInnerAt);
    if (traceShadows) samplePoints();
    meanDirectTransfers();
  }

  template <class Rows>
  void splitRows(const Rows& rows, std::vector<uint32_t>& skyAt, std::vector<uint32_t>& innerAt) const {
    skyAt.resize(rows.rows()), innerAt.resize(rows.rows());
    for (size_t r = 0; r < rows.rows(); ++r) {
      const auto b = rows.node.begin() + rows.start[r], e = rows.node.begin() + rows.start[r + 1];
      const auto sk = std::lower_bound(b, e, op.clusters);
      skyAt[r] = uint32_t(sk - rows.node.begin());
      innerAt[r] = uint32_t(std::lower_bound(sk, e, uint32_t(op.leaves())) - rows.node.begin());
    }
  }

  void samplePoints() {
    rays.emplace(scene);
    const std::vector<glm::vec3> origins = rayOrigins(scene, lay, *rays);
    pointCount.resize(op.clusters);
    for (uint32_t c = 0; c < op.clusters; ++c)
      pointCount[c] = std::min(op.memberStart[c + 1] - op.memberStart[c], uint32_t(op.samplePoints));
    rankStart.assign(1, 0);
    for (uint32_t r = 0; r < uint32_t(op.samplePoints); ++r) {
      for (uint32_t c = 0; c < op.clusters; ++c) {
        if (pointCount[c] <= r) continue;
        const uint32_t v = op.members[op.memberStart[c] + r];
        points.push_back(origins[v]);
        normals.push_back(normalOf(scene, lay, v));
        pointCluster.push_back(c);
        pointSide.push_back(v);
        pointRank.push_back(r);
      }
      rankStart.push_back(uint32_t(points.size()));
    }
    pointShares();
  }

  // Per cluster c, n of its points in use and point r < n: the share of the cluster's area
  // nearest that point among the first n (pointShare[(c · P + n − 1) · P + r], P = samplePoints).
  // The points are spread over the cluster from its centre out, so the later ones stand at its
  // rim: each stands for the members nearest it, not for an equal part.
  void pointShares() {
    const size_t P = size_t(op.samplePoints);
    pointShare.assign(size_t(op.clusters) * P * P, 0.0f);
    tbb::parallel_for(size_t(0), size_t(op.clusters), [&](size_t c) {
      const uint32_t b = op.memberStart[c], e = op.memberStart[c + 1];
      auto position = [&](uint32_t v) { return scene.meshes[lay.meshOfVertex[v]].positions[lay.localVertex(v)]; };
      for (size_t n = 1; n <= pointCount[c]; ++n) {
        float* share = &pointShare[(c * P + n - 1) * P];
        double total = 0.0;
        for (uint32_t i = b; i < e; ++i) {
          const uint32_t v = op.members[i];
          const glm::vec3 x = position(v);
          size_t nearest = 0;
          for (size_t r = 1; r < n; ++r)
            if (glm::length(position(op.members[b + r]) - x) < glm::length(position(op.members[b + nearest]) - x))
              nearest = r;
          const double a = area[v] > 0.0f ? double(area[v]) : 1.0;
          share[nearest] += float(a);
          total += a;
        }
        for (size_t r = 0; r < n; ++r) share[r] = float(share[r] / total);
      }
    });
  }
  float shareOf(uint32_t c, uint32_t used, uint32_t rank) const {
    const size_t P = size_t(op.samplePoints);
    return pointShare[(size_t(c) * P + used - 1) * P + rank];
  }

  glm::vec3 shBounced(size_t v, const sh::ShRgb& l) const { return op::shBounced(scene, lay, v, l); }

  // Inner nodes of one tree (sky or surface) as the weighted means of their children.
  void aggregate(Lights4& v, bool ofSky) const {
    const size_t L = op.leaves();
    for (size_t i = 0; i < op.children.size() / 2; ++i) {
      const size_t n = L + i;
      if ((sky[n] != 0) != ofSky) continue;
      const uint32_t a = op.children[2 * i], b = op.children[2 * i + 1];
      v[n].v = _mm_add_ps(_mm_mul_ps(_mm_set1_ps(childShare[2 * i]), v[a].v),
                          _mm_mul_ps(_mm_set1_ps(childShare[2 * i + 1]), v[b].v));
    }
  }

  // π × (L − L̃) over each bin, L read from the prefiltered maps and L̃ the band-limited sky, at
  // 2 × 2 points of the bin: the sky detail as a radiance per bin, in irradiance units.
  void skyBins(const RigBackground* skyIn, const sh::ShRgb& shLight) {
    skyValue.assign(op.nodes(), kDark);
    if (!skyIn) return;
    const RigBackground f = filtered(*skyIn);
    const int bands = scene.transferBands > 0 ? scene.transferBands : shLight.bands;
    const int n2 = std::min(bands * bands, int(shLight.c.size()));
    binPoints(bands);
    tbb::parallel_for(size_t(0), op.skyBins(), [&](size_t s) {
      glm::dvec3 sum(0.0);
      for (size_t p = 4 * s; p < 4 * s + 4; ++p) {
        const double* y = &binY[p * size_t(bands * bands)];
        glm::dvec3 band(0.0);
        for (int k = 0; k < n2; ++k) band += y[k] * glm::dvec3(shLight.c[size_t(k)]);
        sum += f.radiance(binDir[p]) - band;
      }
      skyValue[op.clusters + s] = light4(glm::vec3(sum * (kPi / 4.0)));
    });
    aggregate(skyValue, true);
  }

  // The bins' 2 × 2 points (binDir: 4 a bin, in the bins' order) and their SH of `bands` bands
  // (binY), computed at the first light change: they are the same at every one.
  void binPoints(int bands) {
    if (binBands == bands) return;
    binBands = bands;
    const int W = op.skyWidth, H = op.skyHeight;
    const size_t n2 = size_t(bands * bands);
    binDir.resize(4 * op.skyBins());
    binY.resize(binDir.size() * n2);
    for (size_t s = 0; s < op.skyBins(); ++s) {
      const int x = int(op.skyBin[s]) % W, y = int(op.skyBin[s]) / W;
      for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j) {
          const size_t p = 4 * s + size_t(2 * i + j);
          binDir[p] = equirectDirection((x + 0.25 + 0.5 * i) / W, (y + 0.25 + 0.5 * j) / H);
          sh::evaluate(bands, binDir[p], &binY[p * n2]);
        }
    }
  }

  // What each cluster gathers from the sky detail (its row's sky leaves and inner nodes: the
  // detail is 0 at surface nodes), R⁰ = ρ (E⁰ + that), then per bounce k the cluster rows'
  // product P_k = G R^k over surface nodes (R^k is 0 at sky nodes, so a row's sky leaves are
  // skipped) and R^{k+1} = ρ P_k. What a cluster gathers from the surfaces is Σ_k P_k = G Σ_k R^k,
  // and `total` ends as Σ_k R^k on the surface tree (0 on the sky's: the detail is skyValue).
  void bounces() {
    const size_t C = op.clusters;
    const BounceOperator::Rows& rows = op.clusterRows;
    clusterSky.assign(C, glm::vec3(0.0f));
    clusterBounce.assign(C, glm::vec3(0.0f));
    total.assign(op.nodes(), kDark);
    tbb::parallel_for(size_t(0), C, [&](size_t c) {
      clusterSky[c] = range(rows.node, clusterW, rowSky[c], rows.start[c + 1], skyValue) * kUnit;
    });
    if (op.bounces == 0) return;
    bounced.assign(op.nodes(), kDark);
    next.assign(op.nodes(), kDark);
    for (size_t c = 0; c < C; ++c) bounced[c] = light4(op.albedo[c] * (clusterE0[c] + clusterSky[c]));
    for (int k = 0; k < op.bounces; ++k) {
      for (size_t c = 0; c < C; ++c) total[c].v = _mm_add_ps(total[c].v, bounced[c].v);
      aggregate(bounced, false);
      const bool last = k + 1 == op.bounces;
      tbb::parallel_for(size_t(0), C, [&](size_t c) {
        const glm::vec3 p = (range(rows.node, clusterW, rows.start[c], rowSky[c], bounced) +
                             range(rows.node, clusterW, rowInner[c], rows.start[c + 1], bounced)) *
                            kUnit;
        clusterBounce[c] += p;
        if (!last) next[c] = light4(op.albedo[c] * p);
      });
      // Inner surface nodes are aggregated again before they are read; sky nodes stay 0 in both.
      std::swap(bounced, next);
    }
    aggregate(total, false);
  }

  // What each gradient row gathers from the surfaces (total) and from the sky (its detail).
  void gradients() {
    const BounceOperator::SignedRows& g = op.clusterGradients;
    if (g.start.empty()) return;
    gradientBounce.assign(g.rows(), glm::vec3(0.0f));
    gradientSky.assign(g.rows(), glm::vec3(0.0f));
    const float unit = 1.0f / float(BounceOperator::kGradientOne);
    tbb::parallel_for(size_t(0), g.rows(), [&](size_t r) {
      gradientBounce[r] = (range(g.node, gradientW, g.start[r], gradientSkyAt[r], total) +
                           range(g.node, gradientW, gradientInnerAt[r], g.start[r + 1], total)) *
                          unit;
      gradientSky[r] = range(g.node, gradientW, gradientSkyAt[r], g.start[r + 1], skyValue) * unit;
    });
  }
  DirectIrradiance vertices(const sh::ShRgb* directSh) const {
    std::vector<glm::vec3> out(op.vertexSides);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, op.vertexSides, 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t v = r.begin(); v != r.end(); ++v) {
        const bool own = op.vertexRows.start[v + 1] > op.vertexRows.start[v];
        const uint32_t c = clusterOf[v];
        if (own) {
          const BounceOperator::Rows& rows = op.vertexRows;
          out[v] = (range(rows.node, vertexW, rows.start[v], rows.start[v + 1], total) +
                    range(rows.node, vertexW, rows.start[v], rows.start[v + 1], skyValue)) *
                   kUnit;
        } else if (st.empty()) {
          out[v] = bounceShare[v] * clusterBounce[c] + skyShare[v] * clusterSky[c];
        } else {
          const float s = st[v].x, t = st[v].y;
          out[v] = bounceShare[v] * (clusterBounce[c] + s * gradientBounce[2 * c] + t * gradientBounce[2 * c + 1]) +
                   skyShare[v] * (clusterSky[c] + s * gradientSky[2 * c] + t * gradientSky[2 * c + 1]);
        }
        if (directSh && op.bounces > 0) out[v] += shBounced(v, *directSh);
      }
    });
    return perInstance(scene, lay, out);
  }

  // E⁰ − t⁰ · directSh at each cluster: its sample points' values, each weighted by the share of
  // the cluster nearest it (pointShares). A light gets the first
  // n of each cluster's points, n in proportion to its share of the strongest light's irradiance
  // (at least 1): a light of a tenth of the strongest's gets one ray per cluster, as its error
  // under few points is a tenth as large in the bounced light.
  void directAtClusters(const std::vector<DirectLight>& lights, const sh::ShRgb* directSh) {
    float strongest = 0.0f;
    for (const DirectLight& l : lights) strongest = std::max(strongest, float(luminance(l.irradiance)));
    ShadowSettings ss;
    ss.samples = 1;
    ss.threads = threads;
    const std::span<const glm::vec3> all(points), allNormals(normals);
    for (const DirectLight& l : lights) {
      const float share = strongest > 0.0f ? float(luminance(l.irradiance)) / strongest : 1.0f;
      const int n = std::clamp(int(std::ceil(float(op.samplePoints) * share)), 1, op.samplePoints);
      const size_t count = rankStart[size_t(n)];
      const std::vector<glm::vec3> e =
          shadowedDirectIrradianceAt(*rays, all.first(count), allNormals.first(count), {l}, ss);
      for (size_t i = 0; i < count; ++i) {
        const uint32_t c = pointCluster[i];
        clusterE0[c] += e[i] * shareOf(c, std::min(pointCount[c], uint32_t(n)), pointRank[i]);
      }
      times.shadowRays += count;
    }
    if (!directSh) return;
    tbb::parallel_for(size_t(0), size_t(op.clusters),
                      [&](size_t c) { clusterE0[c] -= directAt(pointDirect, c, *directSh); });
  }

  // Adds w · t⁰ of vertex side v to cluster c's entry of `mean` (directN2 floats a cluster).
  void addDirect(std::vector<float>& mean, uint32_t c, uint32_t v, float w) const {
    const MeshInstance& m = scene.meshes[lay.meshOfVertex[v]];
    if (!m.hasDirectTransfer()) return;
    const float* t0 = m.directTransferOf(lay.localVertex(v), scene.transferBands, lay.isBack(v));
    for (int k = 0; k < directN2; ++k) mean[c * size_t(directN2) + size_t(k)] += w * t0[k];
  }

  // t⁰ · directSh at cluster c, of the mean transfer `mean`.
  glm::vec3 directAt(const std::vector<float>& mean, size_t c, const sh::ShRgb& directSh) const {
    const size_t n2 = std::min(size_t(directN2), directSh.c.size());
    const float* t0 = &mean[c * size_t(directN2)];
    glm::vec3 e(0.0f);
    for (size_t i = 0; i < n2; ++i) e += t0[i] * glm::vec3(directSh.c[i]);
    return e;
  }

  // Per member (op.members' order), its share of its cluster's light: its area over the
  // cluster's (1 / members where they have no area); per cluster, the mean direct transfer t⁰
  // by those shares (lightFrom's), and by its sample points (light's, with traced shadows).
  void meanDirectTransfers() {
    directN2 = scene.transferBands * scene.transferBands;
    memberShare.resize(op.members.size());
    areaDirect.assign(size_t(op.clusters) * size_t(directN2), 0.0f);
    for (uint32_t c = 0; c < op.clusters; ++c) {
      const uint32_t b = op.memberStart[c], e = op.memberStart[c + 1];
      double weight = 0.0;
      for (uint32_t i = b; i < e; ++i) weight += area[op.members[i]];
      for (uint32_t i = b; i < e; ++i) {
        memberShare[i] = weight > 0.0 ? float(area[op.members[i]] / weight) : 1.0f / float(e - b);
        addDirect(areaDirect, c, op.members[i], memberShare[i]);
      }
    }
    pointDirect.assign(size_t(op.clusters) * size_t(directN2), 0.0f);
    for (size_t i = 0; i < pointSide.size(); ++i)
      addDirect(pointDirect, pointCluster[i], pointSide[i],
                shareOf(pointCluster[i], pointCount[pointCluster[i]], pointRank[i]));
  }

  DirectIrradiance finish(std::chrono::steady_clock::time_point t0, const sh::ShRgb* directSh) {
    auto t = std::chrono::steady_clock::now();
    bounces();
    gradients();
    times.clusters = secondsSince(t);
    t = std::chrono::steady_clock::now();
    DirectIrradiance d = vertices(directSh);
    times.vertices = secondsSince(t);
    d.seconds = secondsSince(t0);
    return d;
  }
};

OperatorLighting::OperatorLighting(const Scene& scene, const BounceOperator& op, bool traceShadows, int threads)
    : impl_(std::make_unique<Impl>(scene, op, traceShadows, threads)) {}

OperatorLighting::~OperatorLighting() = default;

const OperatorTimes& OperatorLighting::lastTimes() const { return impl_->times; }

std::vector<glm::vec3> OperatorLighting::nodeValues() const {
  const Impl& m = *impl_;
  std::vector<glm::vec3> v(m.op.nodes(), glm::vec3(0.0f));
  for (size_t n = 0; n < v.size(); ++n) {
    const Lights4& from = m.sky[n] ? m.skyValue : m.total;
    if (n < from.size()) v[n] = rgb(from[n].v);
  }
  return v;
}

DirectIrradiance OperatorLighting::light(const std::vector<DirectLight>& lights, const sh::ShRgb* directSh,
                                         const RigBackground* sky, const sh::ShRgb& sh) {
  Impl& m = *impl_;
  PRT_CHECK(m.rays.has_value());
  const auto t0 = std::chrono::steady_clock::now();
  const ThreadLimit threadLimit(m.threads);
  m.times = {};
  m.skyBins(sky, sh);
  m.times.sky = secondsSince(t0);
  auto t = std::chrono::steady_clock::now();
  m.clusterE0.assign(m.op.clusters, glm::vec3(0.0f));
  if (!lights.empty() && m.op.bounces > 0) m.directAtClusters(lights, directSh);
  m.times.shadows = secondsSince(t);
  return m.finish(t0, m.op.bounces > 0 && !lights.empty() ? directSh : nullptr);
}

DirectIrradiance OperatorLighting::lightFrom(const DirectIrradiance& e0, const sh::ShRgb* directSh,
                                             const RigBackground* sky, const sh::ShRgb& sh) {
  Impl& m = *impl_;
  const auto t0 = std::chrono::steady_clock::now();
  const ThreadLimit threadLimit(m.threads);
  m.times = {};
  m.skyBins(sky, sh);
  m.times.sky = secondsSince(t0);
  const std::vector<glm::vec3> side = sideValues(m.scene, m.lay, e0);
  // A cluster's light: its members' area-weighted mean (the plain mean where they have no area),
  // as its value stands for the light over its area.
  m.clusterE0.assign(m.op.clusters, glm::vec3(0.0f));
  tbb::parallel_for(size_t(0), size_t(m.op.clusters), [&](size_t c) {
    glm::dvec3 sum(0.0);
    for (uint32_t i = m.op.memberStart[c]; i < m.op.memberStart[c + 1]; ++i)
      sum += double(m.memberShare[i]) * glm::dvec3(side[m.op.members[i]]);
    m.clusterE0[c] = glm::vec3(sum);
    if (directSh) m.clusterE0[c] -= m.directAt(m.areaDirect, c, *directSh);
  });
  return m.finish(t0, m.op.bounces > 0 ? directSh : nullptr);
}

}  // namespace prt::bake
