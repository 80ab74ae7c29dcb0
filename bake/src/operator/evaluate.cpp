// The bounce operator at a light change (prt/bake/bounce_operator.h): sky bins, the direct
// light at the clusters, the bounces cluster to cluster, then one sparse row per vertex side.
#include <chrono>
#include <optional>

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

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

constexpr float kUnit = 1.0f / float(BounceOperator::kWeightOne);

// Σ weight · value over row r.
inline glm::vec3 product(const BounceOperator::Rows& rows, size_t r, const std::vector<glm::vec3>& value) {
  glm::vec3 acc(0.0f);
  for (uint32_t e = rows.start[r]; e < rows.start[r + 1]; ++e) acc += float(rows.weight[e]) * value[rows.node[e]];
  return acc * kUnit;
}

}  // namespace

struct OperatorLighting::Impl {
  const Scene& scene;
  const BounceOperator& op;
  Layout lay;
  int threads;
  std::optional<RayScene> rays;
  std::vector<uint8_t> sky;                // per node: in the sky tree
  std::vector<float> nodeWeight;           // per node: area or solid angle below it
  std::vector<glm::vec3> points, normals;  // the clusters' sample points, cluster by cluster
  std::vector<uint32_t> pointStart;
  std::vector<uint32_t> clusterOf;
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
  std::vector<glm::vec3> skyValue, bounced, next, total, clusterE0;
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
    if (!traceShadows) return;
    rays.emplace(s);
    const std::vector<glm::vec3> origins = rayOrigins(s, lay, rays->sceneExtent());
    pointStart.assign(1, 0);
    for (uint32_t c = 0; c < op.clusters; ++c) {
      const uint32_t b = op.memberStart[c], e = std::min(op.memberStart[c + 1], b + uint32_t(op.samplePoints));
      for (uint32_t i = b; i < e; ++i) {
        points.push_back(origins[op.members[i]]);
        normals.push_back(normalOf(s, lay, op.members[i]));
      }
      pointStart.push_back(uint32_t(points.size()));
    }
  }

  glm::vec3 shDirect(size_t v, const sh::ShRgb& l) const { return op::shDirect(scene, lay, v, l); }
  glm::vec3 shBounced(size_t v, const sh::ShRgb& l) const { return op::shBounced(scene, lay, v, l); }

  // Inner nodes of one tree (sky or surface) as the weighted means of their children.
  void aggregate(std::vector<glm::vec3>& v, bool ofSky) const {
    const size_t L = op.leaves();
    for (size_t i = 0; i < op.children.size() / 2; ++i) {
      const size_t n = L + i;
      if ((sky[n] != 0) != ofSky) continue;
      const uint32_t a = op.children[2 * i], b = op.children[2 * i + 1];
      v[n] = (nodeWeight[a] * v[a] + nodeWeight[b] * v[b]) / nodeWeight[n];
    }
  }

  // π × (L − L̃) over each bin, L read from the prefiltered maps and L̃ the band-limited sky, at
  // 2 × 2 points of the bin: the sky detail as a radiance per bin, in irradiance units.
  void skyBins(const RigBackground* skyIn, const sh::ShRgb& shLight) {
    skyValue.assign(op.nodes(), glm::vec3(0.0f));
    if (!skyIn) return;
    const RigBackground f = filtered(*skyIn);
    const int bands = scene.transferBands > 0 ? scene.transferBands : shLight.bands;
    const int n2 = std::min(bands * bands, int(shLight.c.size()));
    const int W = op.skyWidth, H = op.skyHeight;
    double y[sh::kMaxBands * sh::kMaxBands];
    for (size_t s = 0; s < op.skyBins(); ++s) {
      const int x = int(op.skyBin[s]) % W, yy = int(op.skyBin[s]) / W;
      glm::dvec3 sum(0.0);
      for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j) {
          const glm::dvec3 d = equirectDirection((x + 0.25 + 0.5 * i) / W, (yy + 0.25 + 0.5 * j) / H);
          sh::evaluate(bands, d, y);
          glm::dvec3 band(0.0);
          for (int k = 0; k < n2; ++k) band += y[k] * glm::dvec3(shLight.c[size_t(k)]);
          sum += f.radiance(d) - band;
        }
      skyValue[op.clusters + s] = glm::vec3(sum * (kPi / 4.0));
    }
    aggregate(skyValue, true);
  }

  // R⁰ = ρ (E⁰ + the sky detail at the cluster), then each bounce after the first through the
  // cluster rows; `total` ends as Σ_k R^k on the surface tree and the sky detail on the sky's.
  void bounces() {
    const size_t C = op.clusters;
    total.assign(op.nodes(), glm::vec3(0.0f));
    if (op.bounces > 0) {
      bounced.assign(op.nodes(), glm::vec3(0.0f));
      tbb::parallel_for(size_t(0), C, [&](size_t c) {
        bounced[c] = op.albedo[c] * (clusterE0[c] + product(op.clusterRows, c, skyValue));
      });
      for (size_t c = 0; c < C; ++c) total[c] = bounced[c];
      for (int k = 1; k < op.bounces; ++k) {
        aggregate(bounced, false);
        next.assign(op.nodes(), glm::vec3(0.0f));
        tbb::parallel_for(size_t(0), C,
                          [&](size_t c) { next[c] = op.albedo[c] * product(op.clusterRows, c, bounced); });
        std::swap(bounced, next);
        for (size_t c = 0; c < C; ++c) total[c] += bounced[c];
      }
      aggregate(total, false);
    }
    for (size_t n = 0; n < op.nodes(); ++n)
      if (sky[n]) total[n] = skyValue[n];
  }

  // What each cluster gathers, from the surfaces and from the sky apart, for the vertex sides
  // without a row of their own.
  void clusterLights() {
    clusterBounce.assign(op.clusters, glm::vec3(0.0f));
    clusterSky.assign(op.clusters, glm::vec3(0.0f));
    tbb::parallel_for(size_t(0), size_t(op.clusters), [&](size_t c) {
      glm::vec3 surface(0.0f), fromSky(0.0f);
      for (uint32_t e = op.clusterRows.start[c]; e < op.clusterRows.start[c + 1]; ++e) {
        const uint32_t n = op.clusterRows.node[e];
        (sky[n] ? fromSky : surface) += float(op.clusterRows.weight[e]) * total[n];
      }
      clusterBounce[c] = surface * kUnit, clusterSky[c] = fromSky * kUnit;
    });
    const BounceOperator::SignedRows& g = op.clusterGradients;
    if (g.start.empty()) return;
    gradientBounce.assign(g.rows(), glm::vec3(0.0f));
    gradientSky.assign(g.rows(), glm::vec3(0.0f));
    tbb::parallel_for(size_t(0), g.rows(), [&](size_t r) {
      glm::vec3 surface(0.0f), fromSky(0.0f);
      for (uint32_t e = g.start[r]; e < g.start[r + 1]; ++e)
        (sky[g.node[e]] ? fromSky : surface) += float(g.weight[e]) * total[g.node[e]];
      gradientBounce[r] = surface / float(BounceOperator::kGradientOne);
      gradientSky[r] = fromSky / float(BounceOperator::kGradientOne);
    });
  }

  DirectIrradiance vertices(const sh::ShRgb* directSh) const {
    std::vector<glm::vec3> out(op.vertexSides);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, op.vertexSides, 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t v = r.begin(); v != r.end(); ++v) {
        const bool own = op.vertexRows.start[v + 1] > op.vertexRows.start[v];
        const uint32_t c = clusterOf[v];
        if (own) {
          out[v] = product(op.vertexRows, v, total);
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

  DirectIrradiance finish(std::chrono::steady_clock::time_point t0, const sh::ShRgb* directSh) {
    auto t = std::chrono::steady_clock::now();
    bounces();
    clusterLights();
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

const std::vector<glm::vec3>& OperatorLighting::nodeValues() const { return impl_->total; }

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
  if (!lights.empty() && m.op.bounces > 0) {
    ShadowSettings ss;
    ss.samples = 1;
    ss.threads = m.threads;
    const std::vector<glm::vec3> e = shadowedDirectIrradianceAt(*m.rays, m.points, m.normals, lights, ss);
    for (uint32_t c = 0; c < m.op.clusters; ++c) {
      glm::vec3 sum(0.0f);
      for (uint32_t i = m.pointStart[c]; i < m.pointStart[c + 1]; ++i) {
        sum += e[i];
        if (directSh) sum -= m.shDirect(m.op.members[m.op.memberStart[c] + (i - m.pointStart[c])], *directSh);
      }
      m.clusterE0[c] = sum / float(m.pointStart[c + 1] - m.pointStart[c]);
    }
    m.times.shadowRays = uint64_t(m.points.size()) * lights.size();
  }
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
  for (uint32_t c = 0; c < m.op.clusters; ++c) {
    glm::dvec3 sum(0.0), plain(0.0);
    double weight = 0.0;
    const uint32_t b = m.op.memberStart[c], e = m.op.memberStart[c + 1];
    for (uint32_t i = b; i < e; ++i) {
      const uint32_t v = m.op.members[i];
      const glm::vec3 rest = directSh ? side[v] - m.shDirect(v, *directSh) : side[v];
      sum += double(m.area[v]) * glm::dvec3(rest);
      plain += glm::dvec3(rest);
      weight += m.area[v];
    }
    m.clusterE0[c] = glm::vec3(weight > 0.0 ? sum / weight : plain / double(e - b));
  }
  return m.finish(t0, m.op.bounces > 0 ? directSh : nullptr);
}

}  // namespace prt::bake
