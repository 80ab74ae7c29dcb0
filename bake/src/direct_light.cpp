// Shadowed irradiance of direct lights at baked vertices (prt/bake/direct_light.h).
//
// For a cap C of radiance L around d, the irradiance at x with normal n is
//   E(x) = ∫_C L V(x,ω) max(n·ω, 0) dω = E_unoccluded(n) · [∫_C V w dω / ∫_C w dω],  w = max(n·ω, 0),
// E_unoccluded = E · directCosineFactor(light, n) in closed form (prt/light.h). The bracket, the
// cosine-weighted visible share, is estimated with the same directions in numerator and
// denominator (a ratio estimator): where nothing blocks the cap it is exactly 1, so unshadowed
// surfaces carry no noise and the horizon clipping stays exact; in a penumbra its error is that of
// N stratified samples of a [0, 1] share.
#include "prt/bake/direct_light.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <span>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prt/bake/ray_scene.h"
#include "prt/bake/sampling.h"
#include "prt/error.h"
#include "prt/math.h"
#include "stage_runner.h"
#include "vertex_rays.h"
#include "vertex_sides.h"

namespace prt::bake {

void validate(const ShadowSettings& s) {
  if (s.samples < 1 || s.samples > 65536)
    throw Error(cat("shadow samples ", s.samples, ": must be between 1 and 65536"));
  if (s.threads < 0) throw Error(cat("threads ", s.threads, ": must be 0 (all cores) or more"));
}

namespace {

constexpr uint32_t kStream = 256;

// Directions over one light's cap: uniform in solid angle, cos θ' = 1 − u (1 − cos r), stratified
// by a scrambled Sobol sequence.
struct CapSampler {
  Frame frame;
  double oneMinusCos;  // 2 sin²(r/2), without cancellation for a small sun
  bool delta;
  double sin2;  // sin² of the radius
  explicit CapSampler(const DirectLight& l)
      : frame(Frame::fromNormal(glm::vec3(l.direction))),
        oneMinusCos(2.0 * std::sin(l.radius / 2.0) * std::sin(l.radius / 2.0)),
        delta(l.radius < kPointSunRadians),
        sin2(std::sin(l.radius) * std::sin(l.radius)) {}
  // directCosineFactor(l, n), l the light this samples, without its sines where the cap is
  // wholly above or below n's horizon (where it is cos θ, clamped at 0).
  double cosineFactor(const DirectLight& l, const glm::dvec3& n) const {
    const double cosTheta = std::clamp(glm::dot(n, l.direction), -1.0, 1.0);
    if (delta || cosTheta * cosTheta > sin2) return std::max(cosTheta, 0.0);
    return directCosineFactor(l, n);
  }
  glm::vec3 direction(uint32_t j, uint32_t s0, uint32_t s1) const {
    if (delta) return frame.n;
    const double cosT = 1.0 - double(sobol0(j, s0)) * oneMinusCos;
    const double sinT = std::sqrt(std::max(0.0, 1.0 - cosT * cosT));
    // φ in float: the direction is a float vector, and float's sine and cosine cost half of
    // double's (they were a third of the bounce operator's shadow rays' time).
    const float phi = 2.0f * kPiF * sobol1(j, s1);
    return glm::normalize(
        frame.toWorld(glm::vec3(float(sinT) * std::cos(phi), float(sinT) * std::sin(phi), float(cosT))));
  }
};

// Σ_k E_k · c_k(n) · visible share at one point (ray origin `origin`, unit normal n); `index`
// scrambles the strata (a vertex's global number, a query point's).
glm::dvec3 irradianceAt(const RayScene& rays, const std::vector<CapSampler>& caps,
                        const std::vector<DirectLight>& lights, const glm::vec3& origin, const glm::vec3& n,
                        size_t index, const ShadowSettings& settings, float tnear, uint64_t& count) {
  alignas(64) Ray batch[kStream];
  float weight[kStream];
  glm::dvec3 e(0.0);
  for (size_t li = 0; li < lights.size(); ++li) {
    const DirectLight& light = lights[li];
    const double cosFactor = caps[li].cosineFactor(light, glm::dvec3(n));
    if (cosFactor <= 0.0) continue;  // the whole cap is below the horizon
    const uint64_t h = splitMix64(settings.seed ^ splitMix64(index * lights.size() + li));
    const uint32_t s0 = uint32_t(h), s1 = uint32_t(h >> 32);
    const uint32_t N = caps[li].delta ? 1u : uint32_t(settings.samples);
    double seen = 0.0, total = 0.0;
    for (uint32_t first = 0; first < N; first += kStream) {
      const uint32_t c = std::min(kStream, N - first);
      uint32_t used = 0;
      for (uint32_t j = 0; j < c; ++j) {
        const glm::vec3 dir = caps[li].direction(first + j, s0, s1);
        const float w = caps[li].delta ? 1.0f : glm::dot(n, dir);
        if (w <= 0.0f) continue;  // this part of the cap is below the horizon
        Ray& ray = batch[used];
        ray = Ray{};
        ray.org = origin;
        ray.tnear = tnear;
        ray.dir = dir;
        ray.tfar = std::numeric_limits<float>::infinity();
        weight[used++] = w;
      }
      rays.occluded(batch, used, /*coherent=*/true);  // one origin, one small cone
      count += used;
      for (uint32_t j = 0; j < used; ++j) {
        total += weight[j];
        if (!batch[j].occludedHit()) seen += weight[j];
      }
    }
    if (total > 0.0) e += light.irradiance * (cosFactor * seen / total);
  }
  return e;
}

}  // namespace

namespace {

// Nothing to trace (no light, or no instance with transfer): zero at every baked vertex.
bool nothingToTrace(const Scene& scene, const std::vector<DirectLight>& lights) {
  bool any = false;
  for (const MeshInstance& m : scene.meshes) any |= !m.transfer.empty();
  return !any || lights.empty();
}

DirectIrradiance dark(const Scene& scene) {
  DirectIrradiance out;
  out.front.resize(scene.meshes.size());
  out.back.resize(scene.meshes.size());
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if (!m.transfer.empty()) out.front[k].assign(m.vertexCount(), glm::vec3(0.0f));
    if (m.hasBackTransfer()) out.back[k].assign(m.vertexCount(), glm::vec3(0.0f));
  }
  return out;
}

}  // namespace

DirectIrradiance shadowedDirectIrradiance(const Scene& scene, const std::vector<DirectLight>& lights,
                                          const ShadowSettings& settings) {
  validate(settings);
  if (nothingToTrace(scene, lights)) return dark(scene);
  return shadowedDirectIrradiance(scene, RayScene(scene), lights, settings);
}

DirectIrradiance shadowedDirectIrradiance(const Scene& scene, const RayScene& rays,
                                          const std::vector<DirectLight>& lights, const ShadowSettings& settings,
                                          const std::vector<glm::vec3>* origins) {
  validate(settings);
  const auto t0 = std::chrono::steady_clock::now();
  const ThreadLimit threadLimit(settings.threads);
  if (nothingToTrace(scene, lights)) return dark(scene);
  const float tnear = tnearFor(rays.sceneExtent());
  std::vector<CapSampler> caps;
  for (const DirectLight& l : lights) caps.emplace_back(l);
  return perVertexSide(
      scene, rays, t0,
      [&](const glm::vec3&, const glm::vec3& origin, const glm::vec3& n, size_t index, uint64_t& count) {
        return irradianceAt(rays, caps, lights, origin, n, index, settings, tnear, count);
      },
      origins);
}

std::vector<glm::vec3> shadowedDirectIrradianceAt(const Scene& scene, const std::vector<glm::vec3>& points,
                                                  const std::vector<glm::vec3>& normals,
                                                  const std::vector<DirectLight>& lights,
                                                  const ShadowSettings& settings) {
  validate(settings);
  if (lights.empty() || points.empty()) return std::vector<glm::vec3>(points.size(), glm::vec3(0.0f));
  return shadowedDirectIrradianceAt(RayScene(scene), points, normals, lights, settings);
}

namespace {

// One shadow ray per light and point (settings.samples 1: the bounce operator's rays at its
// clusters' sample points), traced as streams across points instead of one stream call per ray:
// the same directions, weights and results as irradianceAt with one sample.
void oneRayEach(const RayScene& rays, const std::vector<CapSampler>& caps, const std::vector<DirectLight>& lights,
                std::span<const glm::vec3> points, std::span<const glm::vec3> normals, const ShadowSettings& settings,
                float extent, float tnear, std::vector<glm::vec3>& out) {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, points.size(), kStream), [&](const tbb::blocked_range<size_t>& r) {
    alignas(64) Ray batch[kStream];
    size_t who[kStream];
    double gain[kStream];
    std::vector<glm::dvec3> e(r.size(), glm::dvec3(0.0));
    for (size_t li = 0; li < lights.size(); ++li) {
      const DirectLight& light = lights[li];
      uint32_t used = 0;
      auto flush = [&] {
        rays.occluded(batch, used);
        for (uint32_t j = 0; j < used; ++j)
          if (!batch[j].occludedHit()) e[who[j] - r.begin()] += light.irradiance * gain[j];
        used = 0;
      };
      for (size_t i = r.begin(); i < r.end(); ++i) {
        const double cosFactor = caps[li].cosineFactor(light, glm::dvec3(normals[i]));
        if (cosFactor <= 0.0) continue;
        const uint64_t h = splitMix64(settings.seed ^ splitMix64(i * lights.size() + li));
        const glm::vec3 dir = caps[li].direction(0, uint32_t(h), uint32_t(h >> 32));
        const float w = caps[li].delta ? 1.0f : glm::dot(normals[i], dir);
        if (w <= 0.0f) continue;
        Ray& ray = batch[used];
        ray = Ray{};
        ray.org = points[i] + 1e-4f * extent * normals[i];
        ray.tnear = tnear;
        ray.dir = dir;
        ray.tfar = std::numeric_limits<float>::infinity();
        who[used] = i;
        gain[used] = cosFactor * double(w) / double(w);  // as irradianceAt's seen / total
        if (++used == kStream) flush();
      }
      if (used) flush();
    }
    for (size_t i = r.begin(); i < r.end(); ++i) out[i] = glm::vec3(e[i - r.begin()]);
  });
}

}  // namespace

std::vector<glm::vec3> shadowedDirectIrradianceAt(const RayScene& rays, std::span<const glm::vec3> points,
                                                  std::span<const glm::vec3> normals,
                                                  const std::vector<DirectLight>& lights,
                                                  const ShadowSettings& settings) {
  validate(settings);
  PRT_CHECK_EQ(points.size(), normals.size());
  const ThreadLimit threadLimit(settings.threads);
  std::vector<glm::vec3> out(points.size(), glm::vec3(0.0f));
  if (lights.empty() || points.empty()) return out;
  const float extent = rays.sceneExtent(), tnear = tnearFor(extent);
  std::vector<CapSampler> caps;
  for (const DirectLight& l : lights) caps.emplace_back(l);
  if (settings.samples == 1) {
    oneRayEach(rays, caps, lights, points, normals, settings, extent, tnear, out);
    return out;
  }
  tbb::parallel_for(tbb::blocked_range<size_t>(0, points.size(), 16), [&](const tbb::blocked_range<size_t>& r) {
    uint64_t count = 0;
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const glm::vec3 origin = points[i] + 1e-4f * extent * normals[i];
      out[i] = glm::vec3(irradianceAt(rays, caps, lights, origin, normals[i], i, settings, tnear, count));
    }
  });
  return out;
}

}  // namespace prt::bake
