// The one owner of Embree 3 in prt.
#include "prt/bake/ray_scene.h"

#include <cstddef>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include <embree3/rtcore.h>

#include "prt/bake/sampling.h"
#include "prt/error.h"

namespace prt::bake {

// Ray is traced in place as RTCRayHit (and its prefix as RTCRay for occlusion).
static_assert(sizeof(RayPacket8) == sizeof(RTCRayHit8) && alignof(RayPacket8) == alignof(RTCRayHit8));
static_assert(offsetof(RayPacket8, tnear) == offsetof(RTCRayHit8, ray.tnear));
static_assert(offsetof(RayPacket8, dirX) == offsetof(RTCRayHit8, ray.dir_x));
static_assert(offsetof(RayPacket8, tfar) == offsetof(RTCRayHit8, ray.tfar));
static_assert(offsetof(RayPacket8, flags) == offsetof(RTCRayHit8, ray.flags));
static_assert(offsetof(RayPacket8, ngX) == offsetof(RTCRayHit8, hit.Ng_x));
static_assert(offsetof(RayPacket8, u) == offsetof(RTCRayHit8, hit.u));
static_assert(offsetof(RayPacket8, tri) == offsetof(RTCRayHit8, hit.primID));
static_assert(offsetof(RayPacket8, mesh) == offsetof(RTCRayHit8, hit.geomID));
static_assert(offsetof(RayPacket8, inst) == offsetof(RTCRayHit8, hit.instID));
static_assert(sizeof(Ray) == sizeof(RTCRayHit));
static_assert(alignof(Ray) == alignof(RTCRayHit));
static_assert(offsetof(Ray, tnear) == offsetof(RTCRayHit, ray.tnear));
static_assert(offsetof(Ray, dir) == offsetof(RTCRayHit, ray.dir_x));
static_assert(offsetof(Ray, tfar) == offsetof(RTCRayHit, ray.tfar));
static_assert(offsetof(Ray, flags) == offsetof(RTCRayHit, ray.flags));
static_assert(offsetof(Ray, ng) == offsetof(RTCRayHit, hit.Ng_x));
static_assert(offsetof(Ray, u) == offsetof(RTCRayHit, hit.u));
static_assert(offsetof(Ray, tri) == offsetof(RTCRayHit, hit.primID));
static_assert(offsetof(Ray, mesh) == offsetof(RTCRayHit, hit.geomID));
static_assert(offsetof(Ray, inst) == offsetof(RTCRayHit, hit.instID));
static_assert(RTC_INVALID_GEOMETRY_ID == Ray::kInvalid);

// What the filter of an instance that may let light through reads (its geometry's user data).
struct PartialOccluder {
  const Scene* scene;
  const MeshInstance* mesh;
  uint32_t geometry;
};

struct RayScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::string error;                     // first error Embree reported (set by its callback)
  std::vector<PartialOccluder> partial;  // reserved up front: geometries point into it
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

namespace {

// Embree reports through this callback (C code: no exception may cross it). The errors we can
// get are out-of-memory or internal failures; they are recorded and thrown after the build.
void errorCallback(void* user, RTCError code, const char* str) {
  auto& error = *static_cast<std::string*>(user);
  if (!error.empty()) return;
  error = code == RTC_ERROR_OUT_OF_MEMORY ? std::string("out of memory while building the BVH")
                                          : cat("error ", int(code), ": ", str ? str : "");
}

uint32_t floatBits(float x) {
  uint32_t u;
  std::memcpy(&u, &x, sizeof u);
  return u;
}

// Cutouts and partial occluders (docs/bake.md, "Materials as light sees them"). Embree calls
// this for every candidate hit on an instance that may let light through, for intersect and
// occluded rays alike; clearing valid[i] makes the ray go on as if the triangle were not there.
// Opacity 0 (a cutout) always passes, 1 always stops. A partial opacity α is decided by a
// deterministic coin: a hash of the ray (origin and direction bits) and the triangle, stopping
// the ray when the hash's uniform number is below α. So a partial surface is, per ray, either
// a full hit (it shadows, and a bounce gathers the light it reflects) or not there at all: the
// expected transmittance is 1 − α along every path (unbiased), a ray meeting the same triangle
// twice (Embree may test a hit more than once) gets the same answer, and the result depends on
// the ray alone, not on the thread or the order it is traced in.
void partialOccluderFilter(const RTCFilterFunctionNArguments* args) {
  const auto& occ = *static_cast<const PartialOccluder*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const uint32_t tri = RTCHitN_primID(args->hit, args->N, i);
    const float opacity =
        opacityAt(*occ.scene, *occ.mesh, tri, RTCHitN_u(args->hit, args->N, i), RTCHitN_v(args->hit, args->N, i));
    if (opacity >= 1.0f) continue;
    if (opacity > 0.0f) {
      RTCRayN* ray = args->ray;
      const unsigned N = args->N;
      uint64_t h = splitMix64((uint64_t(occ.geometry) << 32) | tri);
      for (float x : {RTCRayN_org_x(ray, N, i), RTCRayN_org_y(ray, N, i), RTCRayN_org_z(ray, N, i),
                      RTCRayN_dir_x(ray, N, i), RTCRayN_dir_y(ray, N, i), RTCRayN_dir_z(ray, N, i)})
        h = splitMix64(h ^ floatBits(x));
      if (float(h >> 40) * 0x1p-24f < opacity) continue;  // stopped
    }
    args->valid[i] = 0;
  }
}

}  // namespace

RayScene::RayScene(const Scene& scene, bool includeReceivers) : impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice("verbose=0");
  if (!impl_->device) throw Error(cat("Embree: cannot create a device (error ", int(rtcGetDeviceError(nullptr)), ")"));
  rtcSetDeviceErrorFunction(impl_->device, errorCallback, &impl_->error);
  impl_->scene = rtcNewScene(impl_->device);
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);

  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  impl_->partial.reserve(scene.meshes.size());
  const std::vector<char> partial = passesLight(scene);
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if ((m.receiverOnly && !includeReceivers) || m.triangleCount() == 0) continue;
    RTCGeometry g = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vb = static_cast<float*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.vertexCount()));
    for (size_t i = 0; i < m.vertexCount(); ++i) {
      std::memcpy(vb + 3 * i, &m.positions[i], 3 * sizeof(float));
      lo = glm::min(lo, m.positions[i]);
      hi = glm::max(hi, m.positions[i]);
    }
    auto* ib = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                              3 * sizeof(uint32_t), m.triangleCount()));
    std::memcpy(ib, m.indices.data(), m.indices.size() * sizeof(uint32_t));
    rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
    if (partial[k]) {
      // Only these get a filter: solid instances keep Embree's full speed.
      impl_->partial.push_back({&scene, &m, static_cast<uint32_t>(k)});
      rtcSetGeometryUserData(g, &impl_->partial.back());
      rtcSetGeometryIntersectFilterFunction(g, partialOccluderFilter);
      rtcSetGeometryOccludedFilterFunction(g, partialOccluderFilter);
    }
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(impl_->scene, g, static_cast<unsigned>(k));
    rtcReleaseGeometry(g);
  }
  rtcCommitScene(impl_->scene);
  if (!impl_->error.empty()) throw Error("Embree: " + impl_->error);
  if (hi.x >= lo.x) extent_ = std::max(glm::length(hi - lo), 1e-6f);
}

RayScene::~RayScene() = default;

void RayScene::intersect(Ray* rays, size_t n, bool coherent) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  for (size_t i = 0; i < n; ++i) {
    rays[i].mesh = Ray::kInvalid;
    rays[i].inst = Ray::kInvalid;
  }
  rtcIntersect1M(impl_->scene, &ctx, reinterpret_cast<RTCRayHit*>(rays), static_cast<unsigned>(n), sizeof(Ray));
}

void RayScene::intersect8(RayPacket8* packets, size_t n) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  for (size_t p = 0; p * 8 < n; ++p) {
    RayPacket8& k = packets[p];
    alignas(32) int valid[8];
    for (size_t l = 0; l < 8; ++l) {
      valid[l] = p * 8 + l < n ? -1 : 0;
      k.mesh[l] = k.inst[l] = Ray::kInvalid;
    }
    rtcIntersect8(valid, impl_->scene, &ctx, reinterpret_cast<RTCRayHit8*>(&k));
  }
}

void RayScene::occluded(Ray* rays, size_t n, bool coherent) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  rtcOccluded1M(impl_->scene, &ctx, reinterpret_cast<RTCRay*>(rays), static_cast<unsigned>(n), sizeof(Ray));
}

}  // namespace prt::bake
