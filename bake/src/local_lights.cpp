// Lights inside the scene on a baked scene (prt/bake/local_lights.h).
//
// For an area light A of radiance L seen from x with normal n,
//   E(x) = ∫_A L V(x, p) cos θ cos θ' / r² dA = E_unoccluded(x, n) · [∫ V w dA / ∫ w dA],  w = cos θ cos θ' / r²,
// E_unoccluded in closed form (prt/local_light.h). As for the suns (direct_light.cpp), the
// bracket is estimated with the same points in numerator and denominator, so an unshadowed
// vertex gets the closed form exactly and a penumbra the error of N stratified samples of a
// [0, 1] share. A sphere is sampled as the cap it subtends (w = cos θ over the cap).
#include "prt/bake/local_lights.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prt/animation.h"
#include "prt/bake/sampling.h"
#include "prt/error.h"
#include "stage_runner.h"
#include "vertex_rays.h"
#include "vertex_sides.h"

namespace prt::bake {

namespace {

struct Placement {
  glm::dvec3 position, direction;
};

// Where a node puts a light at `time`: its origin, and its −Z (KHR_lights_punctual's axis).
Placement nodePlacement(const Scene& scene, int node, double time) {
  const glm::dmat4 world = nodeWorldAt(scene, node, time);
  glm::dvec3 d = glm::dmat3(world) * glm::dvec3(0.0, 0.0, -1.0);
  const double len = glm::length(d);
  return {glm::dvec3(world * glm::dvec4(0.0, 0.0, 0.0, 1.0)), len > 0.0 ? d / len : glm::dvec3(0.0, 0.0, -1.0)};
}

int findNode(const Scene& scene, const std::string& name) {
  for (size_t i = 0; i < scene.nodes.size(); ++i)
    if (scene.nodes[i].name == name) return int(i);
  return -1;
}

}  // namespace

std::vector<LocalLight> scenePunctualLightsAt(const Scene& scene, double time) {
  std::vector<LocalLight> out;
  for (const PunctualLight& p : scene.lights) {
    if (p.type == PunctualLight::Type::Directional) continue;
    LocalLight l;
    l.type = p.type == PunctualLight::Type::Spot ? LocalLight::Type::Spot : LocalLight::Type::Point;
    l.label = cat(scene.path, ": light '", p.name, "'");
    l.position = glm::dvec3(p.position);
    l.direction = glm::normalize(glm::dvec3(p.direction));
    if (p.node >= 0 && isAnimated(scene, p.node)) {
      const Placement at = nodePlacement(scene, p.node, time);
      l.position = at.position;
      l.direction = at.direction;
    }
    l.intensity = glm::dvec3(p.color) * double(p.intensity);
    l.range = p.range;
    l.innerCone = p.innerConeAngle;
    l.outerCone = p.outerConeAngle;
    out.push_back(l);
  }
  return out;
}

std::vector<DirectLight> sceneSunsAt(const Scene& scene, double time) {
  std::vector<DirectLight> out;
  for (const PunctualLight& p : scene.lights) {
    if (p.type != PunctualLight::Type::Directional) continue;
    DirectLight sun;
    glm::dvec3 travel = glm::dvec3(p.direction);
    if (p.node >= 0 && isAnimated(scene, p.node)) travel = nodePlacement(scene, p.node, time).direction;
    sun.direction = -glm::normalize(travel);
    sun.radius = 0.0;
    sun.irradiance = glm::dvec3(p.color) * double(p.intensity);
    out.push_back(sun);
  }
  return out;
}

namespace {

// The emissive texture's mean over triangle `tri` of `m`: 16 texels at stratified barycentric
// points (a 4 × 4 grid of cells folded into the triangle). 1 without a decoded texture.
glm::dvec3 emissiveTextureMean(const Scene& scene, const MeshInstance& m, const TextureSlot& slot, size_t tri) {
  if (slot.texture < 0 || size_t(slot.texture) >= scene.textures.size()) return glm::dvec3(1.0);
  const std::vector<glm::vec2>& uv = m.uvs(slot.uvSet);
  if (uv.size() != m.vertexCount()) return glm::dvec3(1.0);
  const uint32_t* ix = &m.indices[3 * tri];
  glm::dvec3 sum(0.0);
  constexpr int kCells = 4;
  for (int j = 0; j < kCells; ++j)
    for (int i = 0; i < kCells; ++i) {
      double a = (i + 0.5) / kCells, b = (j + 0.5) / kCells;
      if (a + b > 1.0) a = 1.0 - a, b = 1.0 - b;  // fold the square's upper half onto the triangle
      const glm::vec2 at = float(1.0 - a - b) * uv[ix[0]] + float(a) * uv[ix[1]] + float(b) * uv[ix[2]];
      sum += glm::dvec3(glm::vec3(scene.textures[size_t(slot.texture)].sample(at)));
    }
  return sum / double(kCells * kCells);
}

}  // namespace

std::vector<LocalLight> emissiveLightsOf(const Scene& scene) {
  std::vector<LocalLight> out;
  for (const MeshInstance& m : scene.meshes) {
    if (m.receiverOnly || m.material < 0 || size_t(m.material) >= scene.materials.size()) continue;
    const Material& mat = scene.materials[size_t(m.material)];
    const glm::dvec3 base = glm::dvec3(mat.emissiveFactor) * double(mat.emissiveStrength);
    if (!(std::max({base.r, base.g, base.b}) > 0.0)) continue;
    std::vector<LocalLight> tris;
    for (size_t t = 0; 3 * t + 2 < m.indices.size(); ++t) {
      LocalLight l;
      l.type = LocalLight::Type::Triangle;
      l.label = cat(scene.path, ": emissive '", m.name, "'");
      for (int c = 0; c < 3; ++c) l.corners[size_t(c)] = glm::dvec3(m.positions[m.indices[3 * t + size_t(c)]]);
      const glm::dvec3 n = glm::cross(l.corners[1] - l.corners[0], l.corners[2] - l.corners[0]);
      if (!(glm::length(n) > 0.0)) continue;
      l.direction = glm::normalize(n);
      l.position = (l.corners[0] + l.corners[1] + l.corners[2]) / 3.0;
      l.radiance = base * emissiveTextureMean(scene, m, mat.emissiveTexture, t);
      if (!(std::max({l.radiance.r, l.radiance.g, l.radiance.b}) > 0.0)) continue;
      tris.push_back(l);
      if (mat.doubleSided) {
        std::swap(l.corners[1], l.corners[2]);
        l.direction = -l.direction;
        tris.push_back(l);
      }
    }
    if (!tris.empty()) out.push_back(makeEmitter(cat(scene.path, ": surface '", m.name, "'"), std::move(tris)));
  }
  return out;
}

VertexEmission emissionAtVertices(const Scene& scene) {
  VertexEmission out;
  out.front.resize(scene.meshes.size());
  out.back.resize(scene.meshes.size());
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if (m.material < 0 || size_t(m.material) >= scene.materials.size()) continue;
    const Material& mat = scene.materials[size_t(m.material)];
    const glm::vec3 base = mat.emissiveFactor * mat.emissiveStrength;
    if (!(std::max({base.r, base.g, base.b}) > 0.0f)) continue;
    const TextureSlot& slot = mat.emissiveTexture;
    const bool textured = slot.texture >= 0 && size_t(slot.texture) < scene.textures.size() &&
                          m.uvs(slot.uvSet).size() == m.vertexCount();
    std::vector<glm::vec3>& e = out.front[k];
    e.resize(m.vertexCount(), base);
    if (textured)
      for (size_t v = 0; v < m.vertexCount(); ++v)
        e[v] = base * glm::vec3(scene.textures[size_t(slot.texture)].sample(m.uvs(slot.uvSet)[v]));
    if (mat.doubleSided) out.back[k] = e;
  }
  return out;
}

void checkRigNodes(const Scene& scene, const LightRig& rig) {
  for (const RigLocalLight& l : rig.locals)
    if (!l.node.empty() && findNode(scene, l.node) < 0)
      throw Error(cat(rig.source.empty() ? std::string() : rig.source + ": ", l.label, ".node: no node '",
                      printable(l.node), "' in ", scene.path));
}

std::vector<LocalLight> rigLocalLightsAt(const Scene& scene, const LightRig& rig, double frame, double time) {
  std::vector<LocalLight> out;
  for (const RigLocalLight& r : rig.locals) {
    LocalLight l = r.at(frame);
    if (!rig.source.empty()) l.label = cat(rig.source, ": ", r.label);
    if (!r.node.empty()) {
      const int node = findNode(scene, r.node);
      PRT_CHECK(node >= 0);
      const glm::dmat4 world = nodeWorldAt(scene, node, time);
      const glm::dmat3 turn = glm::dmat3(world);
      auto unit = [&](const glm::dvec3& d) {
        const glm::dvec3 w = turn * d;
        return glm::length(w) > 0.0 ? glm::normalize(w) : d;
      };
      l.position = glm::dvec3(world * glm::dvec4(l.position, 1.0));
      l.direction = unit(l.direction);
      l.up = orthogonalTo(l.direction, unit(l.up));
    }
    out.push_back(l);
  }
  return out;
}

namespace {

constexpr uint32_t kStream = 256;
// Shadow rays stop this share short of the light, so a light on a surface is not hidden by it.
constexpr float kShortOfLight = 1e-4f;

// Samples one light from x: a point on it (or, for a sphere, on the cap it subtends) and the
// integrand weight of the ratio estimator (module/docs above). A weight of 0: not traced.
struct LightSampler {
  const LocalLight& l;
  glm::dvec3 t, b;  // the light's own axes (disk, rectangle)
  explicit LightSampler(const LocalLight& light) : l(light) {
    b = orthogonalTo(l.direction, l.up);
    t = glm::cross(b, l.direction);
  }

  // A point on the light for strata (u, v) seen from x, with its weight (0: skip).
  glm::dvec3 point(double u, double v, const glm::dvec3& x, const glm::dvec3& n, double& w) const {
    w = 0.0;
    glm::dvec3 p;
    if (l.type == LocalLight::Type::Sphere) {
      const glm::dvec3 toC = l.position - x;
      const double d = glm::length(toC), sinA = l.radius / d;
      const double oneMinusCos = sinA * sinA / (1.0 + std::sqrt(std::max(0.0, 1.0 - sinA * sinA)));
      const double cosT = 1.0 - u * oneMinusCos, sinT = std::sqrt(std::max(0.0, 1.0 - cosT * cosT));
      const Frame f = Frame::fromNormal(glm::vec3(toC / d));
      const double phi = 2.0 * kPi * v;
      const glm::dvec3 dir = glm::normalize(
          glm::dvec3(f.toWorld(glm::vec3(float(sinT * std::cos(phi)), float(sinT * std::sin(phi)), float(cosT)))));
      // The nearer intersection with the sphere along dir.
      const double bb = glm::dot(dir, toC), disc = std::max(0.0, bb * bb - (d * d - l.radius * l.radius));
      p = x + dir * (bb - std::sqrt(disc));
      w = std::max(0.0, glm::dot(n, dir));
      return p;
    }
    glm::dvec3 facing = l.direction;
    if (l.type == LocalLight::Type::Rectangle) {
      p = l.position + (u - 0.5) * l.width * t + (v - 0.5) * l.height * b;
    } else if (l.type == LocalLight::Type::Triangle || l.type == LocalLight::Type::Emitter) {
      const LocalLight* tri = &l;
      if (l.type == LocalLight::Type::Emitter) {
        // u picks a triangle by its share of the power, then is stretched back over [0, 1).
        const std::vector<double>& cdf = l.emitter->cdf;
        const size_t i = std::min(size_t(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin()), cdf.size() - 1);
        const double lo = i ? cdf[i - 1] : 0.0;
        u = std::clamp((u - lo) / std::max(cdf[i] - lo, 1e-300), 0.0, 1.0);
        tri = &l.emitter->triangles[i];
        facing = tri->direction;
      }
      const double su = std::sqrt(u);  // uniform over the triangle: b0 = 1 − √u, b1 = v √u
      p = (1.0 - su) * tri->corners[0] + su * (1.0 - v) * tri->corners[1] + su * v * tri->corners[2];
    } else {
      const glm::vec2 q = sampleConcentricDisk({float(u), float(v)});
      p = l.position + l.radius * (double(q.x) * t + double(q.y) * b);
    }
    const glm::dvec3 toP = p - x;
    const double r2 = glm::dot(toP, toP);
    if (!(r2 > 0.0)) return p;
    const glm::dvec3 dir = toP / std::sqrt(r2);
    // For an emitter the pdf (∝ luminance × area share) cancels the radiance in the ratio.
    w = std::max(0.0, glm::dot(n, dir)) * std::max(0.0, -glm::dot(facing, dir)) / r2;
    return p;
  }
};

// One shadow ray from `origin` to `target`: whether nothing blocks it.
void aim(Ray& ray, const glm::vec3& origin, const glm::dvec3& target, float tnear) {
  const glm::vec3 to = glm::vec3(target) - origin;
  const float len = glm::length(to);
  ray.start(origin, len > 0.0f ? to / len : glm::vec3(0, 1, 0), tnear, std::max(tnear, len * (1.0f - kShortOfLight)));
}

// The visible share of an area light (or emissive surface) from `origin`: settings.samples rays
// to points stratified over it, the integrand-weighted mean visibility. Its own stream of rays
// (kStream of them, 20 KB to initialise) lives here, so that a vertex lit only by point and
// spot lights, one ray each, does not pay for it.
double areaShare(const RayScene& rays, const LightSampler& sampler, const glm::vec3& origin, const glm::dvec3& xd,
                 const glm::dvec3& nd, uint64_t h, const ShadowSettings& settings, float tnear, uint64_t& count) {
  alignas(64) Ray batch[kStream];
  double weight[kStream];
  const uint32_t s0 = uint32_t(h), s1 = uint32_t(h >> 32), N = uint32_t(settings.samples);
  double seen = 0.0, total = 0.0;
  for (uint32_t first = 0; first < N; first += kStream) {
    const uint32_t c = std::min(kStream, N - first);
    uint32_t used = 0;
    for (uint32_t j = 0; j < c; ++j) {
      double w = 0.0;
      const glm::dvec3 p = sampler.point(sobol0(first + j, s0), sobol1(first + j, s1), xd, nd, w);
      if (w <= 0.0) continue;
      aim(batch[used], origin, p, tnear);
      weight[used++] = w;
    }
    rays.occluded(batch, used, /*coherent=*/true);
    count += used;
    for (uint32_t j = 0; j < used; ++j) {
      total += weight[j];
      if (!batch[j].occludedHit()) seen += weight[j];
    }
  }
  return total > 0.0 ? seen / total : 0.0;
}

// The shadowed irradiance of every light at vertex x (ray origin `origin`, unit normal n).
glm::dvec3 localAt(const RayScene& rays, const std::vector<LocalLight>& lights,
                   const std::vector<LightSampler>& samplers, const glm::vec3& x, const glm::vec3& origin,
                   const glm::vec3& n, size_t index, const ShadowSettings& settings, float tnear, uint64_t& count) {
  glm::dvec3 e(0.0);
  const glm::dvec3 xd(x), nd(n);
  for (size_t li = 0; li < lights.size(); ++li) {
    const LocalLight& l = lights[li];
    const glm::dvec3 open = localIrradiance(l, xd, nd);
    if (!(open.r > 0.0 || open.g > 0.0 || open.b > 0.0)) continue;
    if (l.punctual()) {
      alignas(64) Ray ray;
      aim(ray, origin, l.position, tnear);
      rays.occluded(&ray, 1);
      ++count;
      if (!ray.occludedHit()) e += open;
      continue;
    }
    const uint64_t h = splitMix64(settings.seed ^ splitMix64((index * lights.size() + li) ^ 0x6C6F63616C6C74ull));
    const double share = areaShare(rays, samplers[li], origin, xd, nd, h, settings, tnear, count);
    if (share > 0.0) e += open * share;
  }
  return e;
}

}  // namespace

DirectIrradiance shadowedLocalIrradiance(const Scene& scene, const RayScene& rays,
                                         const std::vector<LocalLight>& lights, const ShadowSettings& settings,
                                         const std::vector<glm::vec3>* origins) {
  validate(settings);
  for (const LocalLight& l : lights) validate(l);
  // No light: every side dark, without walking them (the direct lights' overload does just that
  // for an empty list, and builds no rays).
  if (lights.empty()) return shadowedDirectIrradiance(scene, std::vector<DirectLight>{}, settings);
  const auto t0 = std::chrono::steady_clock::now();
  const ThreadLimit threadLimit(settings.threads);
  const float tnear = tnearFor(rays.sceneExtent());
  std::vector<LightSampler> samplers;
  for (const LocalLight& l : lights) samplers.emplace_back(l);
  return perVertexSide(
      scene, rays, t0,
      [&](const glm::vec3& position, const glm::vec3& origin, const glm::vec3& n, size_t index, uint64_t& count) {
        return localAt(rays, lights, samplers, position, origin, n, index, settings, tnear, count);
      },
      origins);
}

std::vector<glm::vec3> shadowedLocalIrradianceAt(const RayScene& rays, const std::vector<glm::vec3>& points,
                                                 const std::vector<glm::vec3>& normals,
                                                 const std::vector<LocalLight>& lights,
                                                 const ShadowSettings& settings) {
  validate(settings);
  for (const LocalLight& l : lights) validate(l);
  PRT_CHECK_EQ(points.size(), normals.size());
  std::vector<glm::vec3> out(points.size(), glm::vec3(0.0f));
  if (lights.empty()) return out;
  const ThreadLimit threadLimit(settings.threads);
  const float extent = rays.sceneExtent(), tnear = tnearFor(extent);
  std::vector<LightSampler> samplers;
  for (const LocalLight& l : lights) samplers.emplace_back(l);
  tbb::parallel_for(size_t(0), points.size(), [&](size_t i) {
    uint64_t count = 0;
    const glm::vec3 origin = points[i] + 1e-4f * extent * normals[i];
    out[i] = glm::vec3(localAt(rays, lights, samplers, points[i], origin, normals[i], i, settings, tnear, count));
  });
  return out;
}

}  // namespace prt::bake
