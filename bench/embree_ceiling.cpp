// The independent Embree 3 ceiling (embree_ceiling.h). Written against Embree's API alone: no
// prt tracing code, so a choice prt's RayScene makes (a context flag, a stream size, packets or
// single rays) shows up as a gap between the bake and this ceiling instead of being shared.
//
// Modes, for occlusion (rtcOccluded*) and closest hits (rtcIntersect*) alike:
//   1M/<flag>/<M>   AOS streams of M rays (64, 256, 1024), context flag coherent or incoherent
//   1               one ray per call
//   <K>/<flag>      packets of K = 4, 8, 16 rays (SOA), rays of one origin per packet
//   Np/<flag>/256   pointer-SOA streams of 256 rays
// Streams and packets never mix origins except where a stream is longer than one group (1M
// with M = 1024 and 256 rays per vertex spans 4 consecutive vertices, as a bake could).
#include "embree_ceiling.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "cpu_clock.h"
#include "prt/error.h"

namespace prt::bench {

namespace {

void errorCallback(void* user, RTCError code, const char* str) {
  auto& error = *static_cast<std::string*>(user);
  if (error.empty()) error = cat("Embree error ", int(code), ": ", str ? str : "");
}

constexpr unsigned kInvalid = RTC_INVALID_GEOMETRY_ID;

// One lane of an SOA packet or an AOS ray from a bake ray (the hit fields cleared).
template <class R>
void setRay(R& ray, size_t l, const bake::Ray& r) {
  ray.org_x[l] = r.org.x, ray.org_y[l] = r.org.y, ray.org_z[l] = r.org.z, ray.tnear[l] = r.tnear;
  ray.dir_x[l] = r.dir.x, ray.dir_y[l] = r.dir.y, ray.dir_z[l] = r.dir.z, ray.time[l] = 0.0f;
  ray.tfar[l] = r.tfar, ray.mask[l] = ~0u, ray.id[l] = 0, ray.flags[l] = 0;
}
template <class H>
void clearHit(H& hit, size_t l) {
  hit.geomID[l] = kInvalid, hit.primID[l] = kInvalid, hit.instID[0][l] = kInvalid;
}
void setRay1(RTCRay& ray, const bake::Ray& r) {
  ray.org_x = r.org.x, ray.org_y = r.org.y, ray.org_z = r.org.z, ray.tnear = r.tnear;
  ray.dir_x = r.dir.x, ray.dir_y = r.dir.y, ray.dir_z = r.dir.z, ray.time = 0.0f;
  ray.tfar = r.tfar, ray.mask = ~0u, ray.id = 0, ray.flags = 0;
}

RTCIntersectContext context(RTCIntersectContextFlags flags) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = flags;
  return ctx;
}

const char* flagName(RTCIntersectContextFlags f) {
  return f == RTC_INTERSECT_CONTEXT_FLAG_COHERENT ? "coherent" : "incoherent";
}

// One mode: lays the rays out (untimed), traces groups [g0, g1) (timed), counts the rays that
// hit (untimed: every mode must find the same hits, or it did not trace what the others did),
// frees its layout.
struct Mode {
  std::string name;
  std::function<void()> prepare;
  std::function<void(size_t, size_t)> trace;
  std::function<uint64_t()> hits;
  std::function<void()> release;
};

template <class T>
void freeVector(std::vector<T>& v) {
  std::vector<T>().swap(v);
}

}  // namespace

const char* kindName(RayKind kind) { return kind == RayKind::Occlusion ? "occlusion" : "closest-hit"; }

double ModeRate::best(Timing t) const {
  const std::vector<double>& v = raysPerSecond[int(t)];
  return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
}

double ModeRate::median(Timing t) const { return bench::median(raysPerSecond[int(t)]); }

const ModeRate& Ceiling::bestMode(Timing t) const {
  PRT_CHECK(!modes.empty());
  return *std::max_element(modes.begin(), modes.end(),
                           [t](const ModeRate& a, const ModeRate& b) { return a.best(t) < b.best(t); });
}

const ModeRate& Ceiling::bestMedianMode(Timing t) const {
  PRT_CHECK(!modes.empty());
  return *std::max_element(modes.begin(), modes.end(),
                           [t](const ModeRate& a, const ModeRate& b) { return a.median(t) < b.median(t); });
}

nlohmann::json toJson(const Ceiling& c) {
  nlohmann::json j;
  j["kind"] = kindName(c.kind);
  j["rays_per_mode_and_round"] = c.rays;
  for (Timing t : {Timing::Wall, Timing::Cpu}) {
    const std::string suffix = t == Timing::Wall ? "" : "_cpu";
    j["rays_per_s" + suffix] = c.rate(t);
    j["best_mode" + suffix] = c.bestMode(t).mode;
    for (const ModeRate& m : c.modes) {
      const std::vector<double>& v = m.raysPerSecond[int(t)];
      const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
      j["modes"][m.mode]["best" + suffix] = m.best(t);
      j["modes"][m.mode]["range" + suffix] = {*lo, *hi};
    }
  }
  return j;
}

void appendRounds(Ceiling& into, const Ceiling& more) {
  if (into.modes.empty()) {
    into = more;
    return;
  }
  PRT_CHECK_EQ(into.modes.size(), more.modes.size());
  for (size_t k = 0; k < more.modes.size(); ++k)
    for (int t = 0; t < 2; ++t)
      for (double r : more.modes[k].raysPerSecond[t]) into.modes[k].raysPerSecond[t].push_back(r);
}

double roundRate(const Ceiling& c, size_t r, Timing t) {
  double best = 0.0;
  for (const ModeRate& m : c.modes)
    if (r < m.raysPerSecond[int(t)].size()) best = std::max(best, m.raysPerSecond[int(t)][r]);
  return best;
}

struct EmbreeCeiling::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::string error;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

EmbreeCeiling::EmbreeCeiling(const Scene& scene) : impl_(std::make_unique<Impl>()) {
  const auto t0 = Clock::now();
  impl_->device = rtcNewDevice("verbose=0");
  if (!impl_->device) throw Error("ceiling: cannot create an Embree device");
  rtcSetDeviceErrorFunction(impl_->device, errorCallback, &impl_->error);
  impl_->scene = rtcNewScene(impl_->device);
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (const MeshInstance& m : scene.meshes) {
    if (m.receiverOnly || m.triangleCount() == 0) continue;
    RTCGeometry g = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vb = static_cast<float*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.vertexCount()));
    for (size_t i = 0; i < m.vertexCount(); ++i) {
      std::memcpy(vb + 3 * i, &m.positions[i], 3 * sizeof(float));
      lo = glm::min(lo, m.positions[i]);
      hi = glm::max(hi, m.positions[i]);
    }
    auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                              3 * sizeof(unsigned), m.triangleCount()));
    std::memcpy(ib, m.indices.data(), m.indices.size() * sizeof(unsigned));
    rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
    rtcCommitGeometry(g);
    rtcAttachGeometry(impl_->scene, g);
    rtcReleaseGeometry(g);
    triangles_ += m.triangleCount();
  }
  rtcCommitScene(impl_->scene);
  if (!impl_->error.empty()) throw Error("ceiling: " + impl_->error);
  if (hi.x >= lo.x) extent_ = std::max(glm::length(hi - lo), 1e-6f);
  buildSeconds_ = std::chrono::duration<double>(Clock::now() - t0).count();
}

EmbreeCeiling::~EmbreeCeiling() = default;

Ceiling EmbreeCeiling::measure(const std::vector<bake::Ray>& in, size_t group, size_t grain, RayKind kind,
                               int rounds) const {
  PRT_CHECK(group > 0 && grain > 0 && rounds > 0);
  PRT_CHECK_EQ(in.size() % group, size_t(0));
  const size_t n = in.size(), groups = n / group;
  const bool closest = kind == RayKind::ClosestHit;
  RTCScene scene = impl_->scene;
  const RTCIntersectContextFlags kFlags[] = {RTC_INTERSECT_CONTEXT_FLAG_COHERENT,
                                             RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT};
  std::vector<Mode> modes;
  auto forAll = [](size_t count, const std::function<void(size_t)>& f) {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) f(i);
    });
  };

  // ---- AOS rays: 1M streams and single rays.
  std::vector<RTCRayHit> aosHit;
  std::vector<RTCRay> aosRay;
  auto prepareAos = [&] {
    if (closest) {
      aosHit.resize(n);
      forAll(n, [&](size_t i) {
        setRay1(aosHit[i].ray, in[i]);
        aosHit[i].hit.geomID = aosHit[i].hit.primID = aosHit[i].hit.instID[0] = kInvalid;
      });
    } else {
      aosRay.resize(n);
      forAll(n, [&](size_t i) { setRay1(aosRay[i], in[i]); });
    }
  };
  auto aosHits = [&] {
    uint64_t h = 0;
    if (closest)
      for (const RTCRayHit& r : aosHit) h += r.hit.geomID != kInvalid;
    else
      for (const RTCRay& r : aosRay) h += r.tfar < 0.0f;
    return h;
  };
  auto releaseAos = [&] {
    freeVector(aosHit);
    freeVector(aosRay);
  };
  for (RTCIntersectContextFlags flags : kFlags)
    for (size_t m : {64, 256, 1024})
      modes.push_back({cat("1M/", flagName(flags), "/", m), prepareAos,
                       [&, flags, m](size_t g0, size_t g1) {
                         RTCIntersectContext ctx = context(flags);
                         const size_t end = g1 * group;
                         for (size_t i = g0 * group; i < end; i += m) {
                           const unsigned count = unsigned(std::min(m, end - i));
                           if (closest)
                             rtcIntersect1M(scene, &ctx, &aosHit[i], count, sizeof(RTCRayHit));
                           else
                             rtcOccluded1M(scene, &ctx, &aosRay[i], count, sizeof(RTCRay));
                         }
                       },
                       aosHits, releaseAos});
  modes.push_back({"1", prepareAos,
                   [&](size_t g0, size_t g1) {
                     RTCIntersectContext ctx = context(RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
                     for (size_t i = g0 * group; i < g1 * group; ++i)
                       if (closest)
                         rtcIntersect1(scene, &ctx, &aosHit[i]);
                       else
                         rtcOccluded1(scene, &ctx, &aosRay[i]);
                   },
                   aosHits, releaseAos});

  // ---- Packets of K: ceil(group / K) per group, the last one masked. Embree wants the valid
  // masks aligned like the packets (up to 64 bytes).
  struct alignas(64) Valid {
    int lane[16];
  };
  std::vector<Valid> valid;
  auto addPackets = [&](auto packetHit, auto packetRay, auto intersectK, auto occludedK, size_t K) {
    using PH = decltype(packetHit);
    using PR = decltype(packetRay);
    const size_t per = (group + K - 1) / K, packets = groups * per;
    auto hitPackets = std::make_shared<std::vector<PH>>();
    auto rayPackets = std::make_shared<std::vector<PR>>();
    auto prepare = [&, hitPackets, rayPackets, per, packets, K] {
      valid.assign(packets, Valid{});
      if (closest)
        hitPackets->resize(packets);
      else
        rayPackets->resize(packets);
      forAll(packets, [&, per, K](size_t p) {
        const size_t g = p / per, first = (p % per) * K;
        for (size_t l = 0; l < K; ++l) {
          const size_t j = first + l;
          const bake::Ray& r = in[g * group + std::min(j, group - 1)];
          valid[p].lane[l] = j < group ? -1 : 0;
          if (closest) {
            setRay((*hitPackets)[p].ray, l, r);
            clearHit((*hitPackets)[p].hit, l);
          } else {
            setRay((*rayPackets)[p], l, r);
          }
        }
      });
    };
    auto hits = [&, hitPackets, rayPackets, packets, K] {
      uint64_t h = 0;
      for (size_t p = 0; p < packets; ++p)
        for (size_t l = 0; l < K; ++l)
          if (valid[p].lane[l])
            h += closest ? (*hitPackets)[p].hit.geomID[l] != kInvalid : (*rayPackets)[p].tfar[l] < 0.0f;
      return h;
    };
    auto release = [&, hitPackets, rayPackets] {
      freeVector(*hitPackets);
      freeVector(*rayPackets);
      freeVector(valid);
    };
    for (RTCIntersectContextFlags flags : kFlags)
      modes.push_back({cat(K, "/", flagName(flags)), prepare,
                       [&, hitPackets, rayPackets, per, flags, K, intersectK, occludedK](size_t g0, size_t g1) {
                         RTCIntersectContext ctx = context(flags);
                         for (size_t p = g0 * per; p < g1 * per; ++p)
                           if (closest)
                             intersectK(valid[p].lane, scene, &ctx, &(*hitPackets)[p]);
                           else
                             occludedK(valid[p].lane, scene, &ctx, &(*rayPackets)[p]);
                       },
                       hits, release});
  };
  addPackets(RTCRayHit4{}, RTCRay4{}, rtcIntersect4, rtcOccluded4, 4);
  addPackets(RTCRayHit8{}, RTCRay8{}, rtcIntersect8, rtcOccluded8, 8);
  addPackets(RTCRayHit16{}, RTCRay16{}, rtcIntersect16, rtcOccluded16, 16);

  // ---- Pointer-SOA streams of 256 (rtcIntersectNp / rtcOccludedNp).
  std::vector<float> f[13];  // org xyz, tnear, dir xyz, time, tfar, Ng xyz (closest), u
  std::vector<float> fv;     // v
  std::vector<unsigned> mask, id, rflags, primID, geomID, instID;
  auto prepareSoa = [&] {
    for (int k = 0; k < 9; ++k) f[k].resize(n);
    mask.assign(n, ~0u);
    id.assign(n, 0);
    rflags.assign(n, 0);
    if (closest) {
      for (int k = 9; k < 13; ++k) f[k].resize(n);
      fv.resize(n);
      primID.assign(n, kInvalid);
      geomID.assign(n, kInvalid);
      instID.assign(n, kInvalid);
    }
    forAll(n, [&](size_t i) {
      const bake::Ray& r = in[i];
      const float v[9] = {r.org.x, r.org.y, r.org.z, r.tnear, r.dir.x, r.dir.y, r.dir.z, 0.0f, r.tfar};
      for (int k = 0; k < 9; ++k) f[k][i] = v[k];
    });
  };
  auto soaHits = [&] {
    uint64_t h = 0;
    for (size_t i = 0; i < n; ++i) h += closest ? geomID[i] != kInvalid : f[8][i] < 0.0f;
    return h;
  };
  auto releaseSoa = [&] {
    for (auto& v : f) freeVector(v);
    for (auto* v : {&mask, &id, &rflags, &primID, &geomID, &instID}) freeVector(*v);
    freeVector(fv);
  };
  for (RTCIntersectContextFlags flags : kFlags)
    modes.push_back({cat("Np/", flagName(flags), "/256"), prepareSoa,
                     [&, flags](size_t g0, size_t g1) {
                       RTCIntersectContext ctx = context(flags);
                       const size_t end = g1 * group;
                       for (size_t i = g0 * group; i < end; i += 256) {
                         const unsigned count = unsigned(std::min<size_t>(256, end - i));
                         RTCRayHitNp s;
                         s.ray = {&f[0][i], &f[1][i], &f[2][i], &f[3][i], &f[4][i], &f[5][i],
                                  &f[6][i], &f[7][i], &f[8][i], &mask[i], &id[i],   &rflags[i]};
                         if (closest) {
                           s.hit.Ng_x = &f[9][i], s.hit.Ng_y = &f[10][i], s.hit.Ng_z = &f[11][i];
                           s.hit.u = &f[12][i], s.hit.v = &fv[i];
                           s.hit.primID = &primID[i], s.hit.geomID = &geomID[i], s.hit.instID[0] = &instID[i];
                           rtcIntersectNp(scene, &ctx, &s, count);
                         } else {
                           rtcOccludedNp(scene, &ctx, &s.ray, count);
                         }
                       }
                     },
                     soaHits, releaseSoa});

  Ceiling out;
  out.kind = kind;
  out.rays = n;
  out.modes.resize(modes.size());
  std::vector<uint64_t> hitCount(modes.size());
  for (int round = 0; round < rounds; ++round)
    for (size_t k = 0; k < modes.size(); ++k) {
      const Mode& mode = modes[k];
      mode.prepare();
      const double cpu0 = processCpuSeconds();
      const auto t0 = Clock::now();
      tbb::parallel_for(
          tbb::blocked_range<size_t>(0, groups, grain),
          [&](const tbb::blocked_range<size_t>& r) { mode.trace(r.begin(), r.end()); }, tbb::simple_partitioner());
      const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
      const double cpuSeconds = processCpuSeconds() - cpu0;
      hitCount[k] = mode.hits();
      mode.release();
      out.modes[k].mode = mode.name;
      out.modes[k].raysPerSecond[int(Timing::Wall)].push_back(double(n) / seconds);
      out.modes[k].raysPerSecond[int(Timing::Cpu)].push_back(double(n) / cpuSeconds);
      // Every mode traces the same rays: its hits must be those of the first mode, up to the
      // rays that graze an edge (a packet and a single ray may round differently there).
      const double diff = std::fabs(double(hitCount[k]) - double(hitCount[0]));
      if (diff > 1e-4 * double(n) + 1.0)
        throw Error(cat("ceiling: mode ", mode.name, " found ", hitCount[k], " hits, mode ", modes[0].name, " ",
                        hitCount[0], ": the modes did not trace the same rays"));
    }
  if (!impl_->error.empty()) throw Error("ceiling: " + impl_->error);
  return out;
}

}  // namespace prt::bench
