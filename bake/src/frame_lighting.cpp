// The light of a frame on a baked scene (prt/bake/frame_lighting.h).
#include "prt/bake/frame_lighting.h"

#include <algorithm>
#include <chrono>
#include <optional>

#include "prt/bake/bounce_operator.h"
#include "prt/bake/local_lights.h"
#include "prt/bake_record.h"
#include "prt/relight.h"
#include "stage_runner.h"
#include "surface_layout.h"

namespace prt::bake {

namespace {

bool sameLights(const std::vector<DirectLight>& x, const std::vector<DirectLight>& y) {
  return x.size() == y.size() &&
         std::equal(x.begin(), x.end(), y.begin(), [](const DirectLight& p, const DirectLight& q) {
           return p.direction == q.direction && p.radius == q.radius && p.irradiance == q.irradiance;
         });
}

// A bake from before the transfer's direct part: its direct lights go through the whole
// transfer, as they did then. Returns how many.
size_t foldIntoSh(RigLighting& l, int bands) {
  const size_t n = l.direct.size();
  if (n == 0) return 0;
  l.sh += l.directSh;
  l.directSh = sh::ShRgb(bands);
  l.direct.clear();
  return n;
}

// The scene's directional lights join the rig's direct lights (their SH windowed as the rig's),
// or its SH light when direct lights are off.
size_t addSceneSuns(RigLighting& l, const std::vector<DirectLight>& suns, int bands, bool direct, sh::Window window) {
  for (const DirectLight& sun : suns) {
    sh::ShRgb s = sun.project(bands);
    sh::applyWindow(s, window);
    if (direct) {
      l.directSh += s;
      l.direct.push_back(sun);
    } else {
      l.sh += s;
    }
  }
  return direct ? suns.size() : 0;
}

}  // namespace

RigLighting rigLighting(const LightRig& rig, double frame, int bands, bool directLights) {
  if (directLights) return rig.evaluateLighting(frame, bands);
  RigLighting l;
  l.sh = rig.evaluate(frame, bands);
  l.directSh = sh::ShRgb(bands);
  return l;
}

std::vector<glm::vec3> PointShadows::irradiance(const std::vector<glm::vec3>& points,
                                                const std::vector<glm::vec3>& normals,
                                                const std::vector<DirectLight>& lights,
                                                const ShadowSettings& settings) const {
  return shadowedDirectIrradianceAt(rays_, points, normals, lights, settings);
}

std::vector<glm::vec3> PointShadows::irradiance(const std::vector<glm::vec3>& points,
                                                const std::vector<glm::vec3>& normals,
                                                const std::vector<LocalLight>& lights,
                                                const ShadowSettings& settings) const {
  return shadowedLocalIrradianceAt(rays_, points, normals, lights, settings);
}

struct FrameLighting::Impl {
  const Scene& scene;
  const LightRig& rig;
  FrameLightingSettings settings;
  BakeRecord record;
  bool decided = false;
  bool sky = false;          // the sky detail is gathered
  bool traceDirect = false;  // the direct lights' shadow rays are traced
  std::unique_ptr<DirectBounce> gather;
  std::unique_ptr<OperatorLighting> through;  // the bake's operator, where it is used
  std::vector<glm::vec3> nodeValues;          // its node values of the last light change
  std::optional<RayScene> rays;               // the static scene, for the direct lights' shadow rays
  std::vector<glm::vec3> origins;             // the vertex sides' ray origins, made with the first rays
  double setupSeconds = 0.0;
  // The last gather and what it was for.
  DirectIrradiance light;
  std::vector<DirectLight> lightFor;
  std::vector<LocalLight> localFor;
  bool hasLocal = false;                            // lights inside the scene (the same set in every frame)
  std::optional<std::vector<LocalLight>> emissive;  // the scene's emissive triangles
  sh::ShRgb skyFor;
  FrameLightingStats stats;
  // The per-pixel lights' E⁰ of the last update, each light's apart (pixelE0).
  struct LightE0 {
    LocalLight light;
    DirectIrradiance e;
  };
  std::vector<LightE0> pixelLast;

  Impl(const Scene& s, const LightRig& r, const FrameLightingSettings& fs)
      : scene(s), rig(r), settings(fs), record(s.bakeRecord.value_or(BakeRecord{})) {}

  // Which gathers the frames need, from the first frame's lights: the bake's rays gather where
  // the bake kept the direct part, the sky detail unless it is off, and the direct lights'
  // bounces where there are lights and the bake has bounces. Traces the rays.
  // Lights inside the scene are traced at the vertices (for the renderer too), so they need
  // the static scene's rays, and their bounces a gather, whichever way the suns go.
  void decide(const RigLighting& first, bool local) {
    decided = true;
    hasLocal = local;
    const auto t0 = std::chrono::steady_clock::now();
    const bool gatherable = settings.gatherSamples > 0 && settings.directLights && hasDirectTransfer(scene);
    // The sky detail needs a sky: a map, a uniform light or a disk (one too wide to be a direct
    // light goes through SH); suns alone, or lights inside the scene alone, have none.
    const bool anySky = std::any_of(rig.lights.begin(), rig.lights.end(),
                                    [](const RigLight& r) { return r.type != RigLight::Type::Sun; });
    sky = gatherable && settings.skyDetail && anySky;
    const bool sunBounces = gatherable && !first.direct.empty() && record.bounces > 0;
    const bool directBounces = sunBounces || (gatherable && hasLocal && record.bounces > 0);
    traceDirect = settings.directAtVertices ? !first.direct.empty() : sunBounces;
    if ((traceDirect && (settings.directAtVertices || !useOperator())) ||
        (hasLocal && (settings.vertexLight || directBounces)))
      rays.emplace(scene);
    if ((sky || directBounces) && useOperator()) {
      through = std::make_unique<OperatorLighting>(scene, *scene.bounceOperator, !settings.directAtVertices,
                                                   settings.threads);
    } else if (sky || directBounces) {
      BounceSettings bs;
      bs.samples = settings.gatherSamples;
      bs.bounces = record.bounces;
      bs.seed = record.seed;
      bs.threads = settings.threads;
      gather = std::make_unique<DirectBounce>(scene, bs);
      stats.gatherRays = gather->rays();
      stats.traceSeconds = gather->traceSeconds();
    }
    setupSeconds += secondsSince(t0);
  }

  bool useOperator() const { return settings.useOperator && scene.bounceOperator != nullptr; }
  bool gathering() const { return gather != nullptr || through != nullptr; }

  bool needsVertexLight(const RigLighting& l) const {
    if (!settings.vertexLight) return gathering();
    return settings.directAtVertices ? !l.direct.empty() || sky || hasLocal : gathering() || hasLocal;
  }
  bool stale(const RigLighting& l, const std::vector<LocalLight>& local) const {
    return stats.updates == 0 || (sky && l.sh.c != skyFor.c) || !sameLights(l.direct, lightFor) || local != localFor;
  }

  // E⁰, the direct lights' shadowed light (at the vertices, or only what they bounce: dark
  // when nothing of it bounces), plus the sky's detail Δ (added per vertex, and bounced), then
  // their bounces E_b; per pixel the renderer lights E⁰ itself.
  void update(double frame, const RigLighting& l, const std::vector<LocalLight>& local) {
    if (through) return updateThroughOperator(frame, l, local);
    const auto t0 = std::chrono::steady_clock::now();
    DirectIrradiance lit = tracedDirect(l);
    const LocalE0 own = tracedLocal(local);
    if (hasLocal) addIrradiance(lit, own.all);
    DirectIrradiance delta;
    if (sky) {
      delta = gather->skyDetail(rig.shRadiance(frame), l.sh);
      addIrradiance(lit, delta);
      stats.gatherSeconds += delta.seconds;
    }
    if (settings.directAtVertices) {
      if (gather && record.bounces > 0) {
        const DirectIrradiance bounced = gather->bounce(lit);
        addIrradiance(lit, bounced);
        stats.gatherSeconds += bounced.seconds;
      }
      light = std::move(lit);
    } else if (gather) {
      light = gather->bounce(lit);
      stats.gatherSeconds += light.seconds;
      if (sky) addIrradiance(light, delta);
      if (hasLocal) addIrradiance(light, own.atVertices);
    } else {
      light = own.atVertices;  // lights inside the scene without a gather: their direct light alone
    }
    done(l, local, t0);
  }
  void updateThroughOperator(double frame, const RigLighting& l, const std::vector<LocalLight>& local);

  void done(const RigLighting& l, const std::vector<LocalLight>& local, std::chrono::steady_clock::time_point t0) {
    lightFor = l.direct;
    localFor = local;
    skyFor = l.sh;
    stats.updateSeconds += secondsSince(t0);
    ++stats.updates;
  }

  // The lights inside the scene's shadowed light at every vertex (nothing when there are none):
  // `all` of it (what bounces) and what the vertices get (all of it, or with localPerPixel
  // only that of the lights the renderer does not light per pixel). The per-pixel lights' E⁰
  // only bounces, so it takes the bounces' shadow rays (shadowSamples), as the suns' does.
  struct LocalE0 {
    DirectIrradiance all, atVertices;
  };
  LocalE0 tracedLocal(const std::vector<LocalLight>& local) {
    if (!hasLocal) return {};
    const int atVertices = settings.localShadowSamples > 0 ? settings.localShadowSamples : settings.shadowSamples;
    if (!settings.localPerPixel) {
      DirectIrradiance own = tracedLights(local, atVertices);
      return {own, own};
    }
    std::vector<LocalLight> pixel, vertex;
    for (const LocalLight& l : local) (localLightPerPixel(l) ? pixel : vertex).push_back(l);
    LocalE0 own{pixelE0(pixel), tracedLights(vertex, atVertices)};
    addIrradiance(own.all, own.atVertices);
    return own;
  }
  // The per-pixel lights' E⁰ (which only bounces), each light traced alone and kept while it
  // stays as it was: a frame that moves one lamp of several traces that lamp's rays alone.
  DirectIrradiance pixelE0(const std::vector<LocalLight>& pixel) {
    DirectIrradiance sum = tracedLights({}, settings.shadowSamples);  // dark: nothing traced
    std::vector<LightE0> now;
    std::vector<bool> taken(pixelLast.size(), false);
    for (const LocalLight& l : pixel) {
      size_t k = 0;
      while (k < pixelLast.size() && (taken[k] || !(pixelLast[k].light == l))) ++k;
      if (k < pixelLast.size()) {
        taken[k] = true;
        now.push_back(std::move(pixelLast[k]));
      } else {
        now.push_back({l, tracedLights({l}, settings.shadowSamples)});
      }
      addIrradiance(sum, now.back().e);
    }
    pixelLast = std::move(now);
    return sum;
  }
  // The vertex sides' ray origins, made once: finding the buried sides traces rays around each
  // (a start-up cost, as the gather's trace: not a frame's).
  const std::vector<glm::vec3>& sideOrigins() {
    if (origins.empty()) {
      const auto t0 = std::chrono::steady_clock::now();
      origins = rayOrigins(scene, makeLayout(scene), *rays);
      setupSeconds += secondsSince(t0);
    }
    return origins;
  }

  DirectIrradiance tracedLights(const std::vector<LocalLight>& lights, int samples) {
    ShadowSettings ss;
    ss.samples = samples;
    ss.threads = settings.threads;
    DirectIrradiance own = shadowedLocalIrradiance(scene, *rays, lights, ss, &sideOrigins());
    stats.shadowSeconds += own.seconds;
    stats.shadowRays += own.rays;
    return own;
  }

  // The direct lights' shadowed light at every vertex (dark where they are not traced).
  DirectIrradiance tracedDirect(const RigLighting& l) {
    ShadowSettings ss;
    ss.samples = settings.shadowSamples;
    ss.threads = settings.threads;
    DirectIrradiance lit = traceDirect ? shadowedDirectIrradiance(scene, *rays, l.direct, ss, &sideOrigins())
                                       : shadowedDirectIrradiance(scene, {}, ss);
    stats.shadowSeconds += lit.seconds;
    stats.shadowRays += lit.rays;
    return lit;
  }
};

// Through the operator: at the vertices (a relit file) E⁰ traced exactly at every vertex, then
// its bounces and the sky detail as products; for the renderer (which lights E⁰ per pixel)
// only the products, E⁰ taken at the clusters' sample points.
// With lights inside the scene, their E⁰ at every vertex joins the suns' (traced at the vertices
// then, for the renderer too) and goes in through lightFrom; the renderer then gets their E⁰ at
// the vertices as well, the suns' staying per pixel.
void FrameLighting::Impl::updateThroughOperator(double frame, const RigLighting& l,
                                                const std::vector<LocalLight>& local) {
  const auto t0 = std::chrono::steady_clock::now();
  const RigBackground skyLight = sky ? rig.shRadiance(frame) : RigBackground{};
  const RigBackground* skyOrNull = sky ? &skyLight : nullptr;
  const std::vector<DirectLight> bouncing = record.bounces > 0 ? l.direct : std::vector<DirectLight>{};
  if (settings.directAtVertices) {
    DirectIrradiance lit = tracedDirect(l);
    if (hasLocal) addIrradiance(lit, tracedLocal(local).all);
    const DirectIrradiance more = through->lightFrom(lit, &l.directSh, skyOrNull, l.sh);
    addIrradiance(lit, more);
    light = std::move(lit);
  } else if (!hasLocal) {
    light = through->light(bouncing, &l.directSh, skyOrNull, l.sh);
  } else {
    DirectIrradiance lit = tracedDirect(l);
    const LocalE0 own = tracedLocal(local);
    addIrradiance(lit, own.all);
    light = through->lightFrom(lit, &l.directSh, skyOrNull, l.sh);
    addIrradiance(light, own.atVertices);
  }
  const OperatorTimes& t = through->lastTimes();
  stats.shadowSeconds += t.shadows;
  stats.shadowRays += t.shadowRays;
  stats.gatherSeconds += t.sky + t.clusters + t.vertices;
  stats.skySeconds += t.sky, stats.clusterSeconds += t.clusters, stats.vertexSeconds += t.vertices;
  done(l, local, t0);
}

FrameLighting::FrameLighting(const Scene& scene, const LightRig& rig, const FrameLightingSettings& settings)
    : impl_(std::make_unique<Impl>(scene, rig, settings)) {
  checkRigNodes(scene, rig);
}

FrameLighting::~FrameLighting() = default;

FrameLight FrameLighting::at(double frame) {
  Impl& m = *impl_;
  const auto t0 = std::chrono::steady_clock::now();
  const double setup0 = m.setupSeconds;
  const int bands = m.scene.transferBands;
  FrameLight out;
  out.rig = rigLighting(m.rig, frame, bands, m.settings.directLights);
  // The scene's animation time of this frame, for lights on nodes it moves.
  const double time = frame / m.rig.fps.value_or(kDefaultLightFps);
  if (m.settings.sceneLights) {
    out.sceneSuns = addSceneSuns(out.rig, sceneSunsAt(m.scene, time), bands, m.settings.directLights, m.rig.window);
    out.local = scenePunctualLightsAt(m.scene, time);
    if (!m.emissive) m.emissive = emissiveLightsOf(m.scene);  // static: computed once
    out.local.insert(out.local.end(), m.emissive->begin(), m.emissive->end());
  }
  for (LocalLight& l : rigLocalLightsAt(m.scene, m.rig, frame, time)) out.local.push_back(std::move(l));
  if (m.settings.directAtVertices && !hasDirectTransfer(m.scene)) out.foldedLights = foldIntoSh(out.rig, bands);
  if (!m.decided) m.decide(out.rig, !out.local.empty());
  if (m.needsVertexLight(out.rig)) {
    out.updated = m.stale(out.rig, out.local);
    if (out.updated) m.update(frame, out.rig, out.local);
    out.vertexLight = &m.light;
    // Only the probes' rows read the node values: copied out for a bake that has them.
    if (m.through && m.scene.bounceOperator->probeRows.present()) {
      if (out.updated || m.nodeValues.empty()) m.nodeValues = m.through->nodeValues();
      out.operatorValues = &m.nodeValues;
    }
  }
  // The bounces gathered here do not also go through the transfer's (t − t⁰) · directSh.
  if (m.settings.directAtVertices && m.gathering()) out.rig.directSh = sh::ShRgb(bands);
  out.seconds = secondsSince(t0) - (m.setupSeconds - setup0);
  return out;
}

bool FrameLighting::gathers() const { return impl_->gathering(); }
bool FrameLighting::usesOperator() const { return impl_->through != nullptr; }
bool FrameLighting::skyDetail() const { return impl_->sky; }
const FrameLightingStats& FrameLighting::stats() const { return impl_->stats; }
const RayScene* FrameLighting::rays() const { return impl_->rays ? &*impl_->rays : nullptr; }

}  // namespace prt::bake
