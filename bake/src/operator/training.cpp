// The operator's training lights and transfer shares (training.h).
#include "training.h"

#include <cmath>
#include <limits>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../surface_layout.h"
#include "prt/bake/direct_light.h"
#include "prt/light.h"
#include "prt/math.h"
#include "prt/sh.h"

namespace prt::bake::op {

namespace {

// n directions spread evenly over the sphere (a Fibonacci lattice, y up), turned by `phase`.
std::vector<glm::dvec3> spread(int n, double phase) {
  std::vector<glm::dvec3> d(static_cast<size_t>(n));
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double y = 1.0 - (2.0 * i + 1.0) / n, r = std::sqrt(std::max(0.0, 1.0 - y * y));
    const double phi = golden * i + phase;
    d[size_t(i)] = {r * std::cos(phi), y, r * std::sin(phi)};
  }
  return d;
}

// The training skies' disks: 10° across, each sending a quarter of the sun's irradiance (a
// clear sky's share), as π L = E / sin² r.
constexpr double kDiskRadius = 10.0 * kPi / 180.0;
constexpr double kDiskIrradiance = 0.25;
// The dim uniform sky under which a receiver's light is judged: irradiance 0.25 unoccluded.
constexpr double kAmbientIrradiance = 0.25;
// A training lamp's mean irradiance over the vertex sides.
constexpr double kLampMeanIrradiance = 0.25;

}  // namespace

glm::vec3 shDirect(const Scene& scene, const Layout& lay, size_t v, const sh::ShRgb& l) {
  const MeshInstance& m = scene.meshes[lay.meshOfVertex[v]];
  if (!m.hasDirectTransfer()) return glm::vec3(0.0f);
  const int bands = scene.transferBands, n2 = std::min(bands * bands, int(l.c.size()));
  const float* t0 = m.directTransferOf(lay.localVertex(v), bands, lay.isBack(v));
  glm::vec3 e(0.0f);
  for (int i = 0; i < n2; ++i) e += t0[i] * l.c[size_t(i)];
  return e;
}

glm::vec3 shBounced(const Scene& scene, const Layout& lay, size_t v, const sh::ShRgb& l) {
  const MeshInstance& m = scene.meshes[lay.meshOfVertex[v]];
  if (!m.hasDirectTransfer()) return glm::vec3(0.0f);
  const int bands = scene.transferBands, n2 = std::min(bands * bands, int(l.c.size()));
  const bool back = lay.isBack(v);
  const size_t local = lay.localVertex(v);
  if (back && !m.hasBackTransfer()) return glm::vec3(0.0f);
  const glm::vec3* t = back ? m.backTransferOf(local, bands) : m.transferOf(local, bands);
  const float* t0 = m.directTransferOf(local, bands, back);
  glm::vec3 e(0.0f);
  for (int i = 0; i < n2; ++i) e += (t[i] - glm::vec3(t0[i])) * l.c[size_t(i)];
  return e;
}

TransferShares transferShares(const Scene& scene, const Layout& lay, const BounceOperator& op,
                              const std::vector<float>& area) {
  TransferShares s;
  s.bounce.assign(op.vertexSides, 1.0f);
  s.sky.assign(op.vertexSides, 1.0f);
  sh::ShRgb white(scene.transferBands > 0 ? scene.transferBands : 1);
  white.c[0] = glm::vec3(1.0f);
  std::vector<float> b(op.vertexSides), d(op.vertexSides);
  for (size_t v = 0; v < op.vertexSides; ++v)
    b[v] = luminance(shBounced(scene, lay, v, white)), d[v] = luminance(shDirect(scene, lay, v, white));
  for (uint32_t c = 0; c < op.clusters; ++c) {
    double sb = 0.0, sd = 0.0, w = 0.0;
    for (uint32_t i = op.memberStart[c]; i < op.memberStart[c + 1]; ++i) {
      const uint32_t v = op.members[i];
      sb += double(area[v]) * b[v], sd += double(area[v]) * d[v], w += area[v];
    }
    if (!(w > 0.0)) continue;
    for (uint32_t i = op.memberStart[c]; i < op.memberStart[c + 1]; ++i) {
      const uint32_t v = op.members[i];
      if (sb > 0.0) s.bounce[v] = float(b[v] * w / sb);
      if (sd > 0.0) s.sky[v] = float(d[v] * w / sd);
    }
  }
  return s;
}

std::vector<glm::vec2> clusterCoordinates(const Scene& scene, const Layout& lay, const BounceOperator& op,
                                          const std::vector<float>& area) {
  std::vector<glm::vec2> st(op.vertexSides, glm::vec2(0.0f));
  auto position = [&](uint32_t v) {
    return glm::dvec3(scene.meshes[lay.meshOfVertex[v]].positions[lay.localVertex(v)]);
  };
  tbb::parallel_for(uint32_t(0), op.clusters, [&](uint32_t c) {
    const uint32_t b = op.memberStart[c], e = op.memberStart[c + 1];
    glm::dvec3 centroid(0.0), mean(0.0), normal(0.0);
    double w = 0.0;
    for (uint32_t i = b; i < e; ++i) {
      const uint32_t v = op.members[i];
      centroid += double(area[v]) * position(v), mean += position(v), w += area[v];
      normal += glm::dvec3(normalOf(scene, lay, v));
    }
    centroid = w > 0.0 ? centroid / w : mean / double(e - b);
    double radius = 0.0;
    for (uint32_t i = b; i < e; ++i) radius = std::max(radius, glm::length(position(op.members[i]) - centroid));
    if (!(radius > 0.0) || !(glm::length(normal) > 0.0)) return;
    // An orthonormal basis around the normal (Duff et al. 2017).
    const glm::dvec3 n = glm::normalize(normal);
    const double sign = std::copysign(1.0, n.z), a = -1.0 / (sign + n.z), bb = n.x * n.y * a;
    const glm::dvec3 t1(1.0 + sign * n.x * n.x * a, sign * bb, -sign * n.x);
    const glm::dvec3 t2(bb, sign + n.y * n.y * a, -n.y);
    for (uint32_t i = b; i < e; ++i) {
      const uint32_t v = op.members[i];
      const glm::dvec3 d = (position(v) - centroid) / radius;
      st[v] = glm::vec2(float(glm::dot(d, t1)), float(glm::dot(d, t2)));
    }
  });
  return st;
}

namespace {

// Per sky bin and training light: π (L − L̃) at 2 × 2 points of the bin for a sun's disk (0 for
// a lamp).
void skyResidual(const Scene& scene, const BounceOperator& op, std::vector<float>& out) {
  constexpr int K = kTrainingLights;
  const int bands = scene.transferBands > 0 ? scene.transferBands : 1;
  const std::vector<glm::dvec3> disks = spread(kTrainingSuns, 1.0);
  const double piL = kDiskIrradiance / (std::sin(kDiskRadius) * std::sin(kDiskRadius));
  const double cosR = std::cos(kDiskRadius);
  const int W = op.skyWidth, H = op.skyHeight;
  out.assign(op.skyBins() * K, 0.0f);
  for (int k = 0; k < kTrainingSuns; ++k) {
    const sh::ShRgb band = projectDiskRadiance(bands, disks[size_t(k)], kDiskRadius, glm::dvec3(piL));
    for (size_t s = 0; s < op.skyBins(); ++s) {
      const int x = int(op.skyBin[s]) % W, y = int(op.skyBin[s]) / W;
      double sum = 0.0;
      for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j) {
          const glm::dvec3 d = equirectDirection((x + 0.25 + 0.5 * i) / W, (y + 0.25 + 0.5 * j) / H);
          sum += (glm::dot(d, disks[size_t(k)]) >= cosR ? piL : 0.0) - double(sh::reconstruct(band, glm::vec3(d)).r);
        }
      out[s * K + size_t(k)] = float(sum / 4.0);
    }
  }
}

// The training lamps' positions: point lights in front of surfaces spread over the scene, where a level's
// lamps hang. From the vertex side nearest the scene's centre, then each time the side farthest
// from those chosen, each lamp stands off its side along the side's normal, half way to what
// the normal meets (at most a tenth of the scene's extent), so that it lights the room the side
// faces. Sides whose normal meets something within a thousandth of the extent are passed over.
std::vector<glm::vec3> trainingLamps(const Layout& lay, const RayScene& rays, const std::vector<glm::vec3>& origins,
                                     const std::vector<glm::vec3>& normals) {
  const size_t V = lay.vertices;
  const float extent = rays.sceneExtent(), tnear = tnearFor(extent);
  glm::dvec3 centre(0.0);
  for (size_t v = 0; v < V; ++v) centre += glm::dvec3(origins[v]) / double(V);
  size_t pick = 0;
  for (size_t v = 1; v < V; ++v)
    if (glm::length(glm::dvec3(origins[v]) - centre) < glm::length(glm::dvec3(origins[pick]) - centre)) pick = v;
  std::vector<float> nearest(V, std::numeric_limits<float>::infinity());
  std::vector<glm::vec3> lamps;
  for (size_t tries = 0; lamps.size() < size_t(kTrainingLamps) && tries < 4 * size_t(kTrainingLamps); ++tries) {
    if (tries > 0) {
      for (size_t v = 0; v < V; ++v)
        if (nearest[v] > nearest[pick]) pick = v;  // the farthest from those chosen
    }
    for (size_t v = 0; v < V; ++v) nearest[v] = std::min(nearest[v], glm::length(origins[v] - origins[pick]));
    Ray r;
    r.start(origins[pick], normals[pick], tnear, std::numeric_limits<float>::infinity());
    rays.intersect(&r, 1);
    const float free = r.hit() ? r.tfar : std::numeric_limits<float>::infinity();
    if (!(free > 1e-3f * extent)) continue;
    lamps.push_back(origins[pick] + normals[pick] * std::min(0.5f * free, 0.1f * extent));
  }
  return lamps;
}

// Per vertex side and lamp (side-major): a lamp of unit intensity's irradiance cos θ / d² at
// the side, 0 where something stands between them: one shadow ray per side and lamp, in streams.
std::vector<float> lampIrradiance(const RayScene& rays, const std::vector<glm::vec3>& lamps,
                                  const std::vector<glm::vec3>& origins, const std::vector<glm::vec3>& normals) {
  constexpr size_t kStream = 256;
  const size_t L = lamps.size();
  std::vector<float> out(origins.size() * L, 0.0f);
  const float tnear = tnearFor(rays.sceneExtent());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, origins.size(), kStream), [&](const tbb::blocked_range<size_t>& r) {
    alignas(64) Ray batch[kStream];
    size_t who[kStream];
    float value[kStream];
    for (size_t k = 0; k < L; ++k) {
      const glm::vec3 at = lamps[k];
      size_t used = 0;
      auto flush = [&] {
        rays.occluded(batch, used);
        for (size_t q = 0; q < used; ++q)
          if (!batch[q].occludedHit()) out[who[q] * L + k] = value[q];
        used = 0;
      };
      for (size_t v = r.begin(); v < r.end(); ++v) {
        const glm::vec3 d = at - origins[v];
        const float d2 = glm::dot(d, d), cosine = glm::dot(normals[v], d);
        if (!(d2 > 0.0f) || cosine <= 0.0f) continue;
        const float dist = std::sqrt(d2);
        batch[used].start(origins[v], d / dist, tnear, dist * (1.0f - 1e-4f));
        who[used] = v, value[used] = cosine / (d2 * dist);
        if (++used == kStream) flush();
      }
      flush();
    }
  });
  return out;
}

}  // namespace

SideTraining trainSides(const Scene& scene, const Layout& lay, const RayScene& rays,
                        const std::vector<glm::vec3>& origins) {
  constexpr int K = kTrainingLights;
  SideTraining t;
  const size_t V = lay.vertices;
  const int bands = scene.transferBands > 0 ? scene.transferBands : 1;
  std::vector<glm::vec3> normals(V);
  for (size_t v = 0; v < V; ++v) normals[v] = normalOf(scene, lay, v);
  t.residual.assign(V * K, 0.0f);
  t.scale.assign(V, 0.0f);
  const std::vector<glm::dvec3> suns = spread(kTrainingSuns, 0.0);
  ShadowSettings ss;
  ss.samples = 1;
  for (int k = 0; k < kTrainingSuns; ++k) {
    DirectLight sun;
    sun.direction = suns[size_t(k)];
    sun.irradiance = glm::dvec3(1.0);
    const std::vector<glm::vec3> e0 = shadowedDirectIrradianceAt(rays, origins, normals, {sun}, ss);
    const sh::ShRgb l = sun.project(bands);
    tbb::parallel_for(size_t(0), V, [&](size_t v) {
      const float direct = luminance(e0[v]);
      t.residual[v * K + size_t(k)] = direct - luminance(shDirect(scene, lay, v, l));
      t.scale[v] += (direct + std::max(0.0f, luminance(shBounced(scene, lay, v, l)))) / float(K);
    });
  }
  // Each lamp scaled so that its vertex sides' mean irradiance is a quarter (a training sun's
  // unit irradiance over sides facing every way; in a closed level no sun lights anything).
  const std::vector<glm::vec3> lamps = trainingLamps(lay, rays, origins, normals);
  const std::vector<float> lit = lampIrradiance(rays, lamps, origins, normals);
  for (size_t k = 0; k < lamps.size(); ++k) {
    double mean = 0.0;
    for (size_t v = 0; v < V; ++v) mean += double(lit[v * lamps.size() + k]) / double(V);
    const float scale = mean > 0.0 ? float(kLampMeanIrradiance / mean) : 0.0f;
    tbb::parallel_for(size_t(0), V, [&](size_t v) {
      const float e = std::min(scale * lit[v * lamps.size() + k], float(4.0 * kLampMeanIrradiance));
      t.residual[v * K + size_t(kTrainingSuns) + k] = e;
      t.scale[v] += e / float(K);
    });
  }
  const sh::ShRgb ambient = projectUniform(bands, glm::dvec3(kAmbientIrradiance / kPi));
  tbb::parallel_for(size_t(0), V, [&](size_t v) {
    t.scale[v] += luminance(shDirect(scene, lay, v, ambient) + shBounced(scene, lay, v, ambient));
  });
  return t;
}

Training trainNodes(const Scene& scene, const BounceOperator& op, const SideTraining& sides,
                    const std::vector<float>& area) {
  constexpr int K = kTrainingLights;
  Training t;
  t.value.assign(op.nodes() * K, 0.0f);
  std::vector<float> skyValues;
  skyResidual(scene, op, skyValues);
  tbb::parallel_for(uint32_t(0), op.clusters, [&](uint32_t c) {
    double w = 0.0;
    std::vector<double> sum(K, 0.0), plain(K, 0.0);
    for (uint32_t i = op.memberStart[c]; i < op.memberStart[c + 1]; ++i) {
      const uint32_t v = op.members[i];
      for (int k = 0; k < K; ++k) {
        sum[size_t(k)] += double(area[v]) * sides.residual[size_t(v) * K + size_t(k)];
        plain[size_t(k)] += sides.residual[size_t(v) * K + size_t(k)];
      }
      w += area[v];
    }
    const double members = double(op.memberStart[c + 1] - op.memberStart[c]);
    const float rho = luminance(op.albedo[c]);
    for (int k = 0; k < K; ++k)
      t.value[size_t(c) * K + size_t(k)] = rho * float(w > 0.0 ? sum[size_t(k)] / w : plain[size_t(k)] / members);
  });
  std::copy(skyValues.begin(), skyValues.end(), t.value.begin() + ptrdiff_t(size_t(op.clusters) * K));
  // Inner nodes: the weighted means of their children (children come before parents).
  const std::vector<float> weight = nodeWeights(op);
  for (size_t i = 0; i < op.children.size() / 2; ++i) {
    const size_t n = op.leaves() + i;
    const uint32_t a = op.children[2 * i], b = op.children[2 * i + 1];
    const float wa = weight[n] > 0.0f ? weight[a] / weight[n] : 0.5f;
    for (int k = 0; k < K; ++k)
      t.value[n * K + size_t(k)] =
          wa * t.value[size_t(a) * K + size_t(k)] + (1.0f - wa) * t.value[size_t(b) * K + size_t(k)];
  }
  return t;
}

}  // namespace prt::bake::op
