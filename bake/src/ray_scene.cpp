// The one owner of Embree 3 in prt.
#include "prt/bake/ray_scene.h"

#include <cstddef>
#include <cstring>
#include <limits>
#include <string>

#include <embree3/rtcore.h>

#include "prt/error.h"

namespace prt::bake {

// Ray is traced in place as RTCRayHit (and its prefix as RTCRay for occlusion).
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

struct RayScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::string error;  // first error Embree reported (set by its callback)
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

}  // namespace

RayScene::RayScene(const Scene& scene, bool includeReceivers) : impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice("verbose=0");
  if (!impl_->device) throw Error(cat("Embree: cannot create a device (error ", int(rtcGetDeviceError(nullptr)), ")"));
  rtcSetDeviceErrorFunction(impl_->device, errorCallback, &impl_->error);
  impl_->scene = rtcNewScene(impl_->device);
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);

  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    if ((m.receiverOnly && !includeReceivers) || m.triangleCount() == 0) continue;
    RTCGeometry g = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(
        g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.vertexCount()));
    for (size_t i = 0; i < m.vertexCount(); ++i) {
      std::memcpy(vb + 3 * i, &m.positions[i], 3 * sizeof(float));
      lo = glm::min(lo, m.positions[i]);
      hi = glm::max(hi, m.positions[i]);
    }
    auto* ib = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
        g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), m.triangleCount()));
    std::memcpy(ib, m.indices.data(), m.indices.size() * sizeof(uint32_t));
    rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
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
  rtcIntersect1M(impl_->scene, &ctx, reinterpret_cast<RTCRayHit*>(rays), static_cast<unsigned>(n),
                 sizeof(Ray));
}

void RayScene::occluded(Ray* rays, size_t n, bool coherent) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  rtcOccluded1M(impl_->scene, &ctx, reinterpret_cast<RTCRay*>(rays), static_cast<unsigned>(n),
                sizeof(Ray));
}

}  // namespace prt::bake
