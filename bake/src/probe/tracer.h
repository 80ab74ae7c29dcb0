// The per-probe estimator of the probe bake (docs/prt-math.md, docs/probes.md):
//   M_ji(p) = ∫ y_j(ω) [ V(p,ω) y_i(ω) + (1 − V(p,ω)) (ρ(h)/π) t_i(h(ω)) ] dω
// estimated with N uniform sphere directions (pdf 1/4π): each ray adds (4π/N) y_j(ω) [...].
// A ray that hits the back of a one-sided surface sends nothing, and counts towards the probe's
// back-face share: a probe that sees mostly back faces is inside geometry. The back of a
// double-sided surface is a lit surface like any front: it sends its back side's transfer
// (the second half of lowerOrder[k], surface_bake.h) and is a sign of being inside only where
// back faces of any kind surround the probe (more than kSolidShare of its rays: solid mass
// bounded by double-sided faces, as maps exported with every material double-sided have; a
// probe under a double-sided roof sees them over half its sphere at most). Per cube face the
// probe also keeps the mean and mean square of its hits' depth along the face's axis, for the
// interpolation's visibility test.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "../trace_clock.h"
#include "probe_types.h"
#include "prt/bake/albedo_lookup.h"
#include "prt/bake/ray_scene.h"
#include "prt/scene.h"

namespace prt::bake::probe {

struct Tracer {
  const Scene& scene;
  const RayScene& rays;
  // The lower-order surface transfer as halves, per instance (its rows: vertex × side; empty
  // where the instance has none, and no entries without bounces): what litMeshes points into.
  const std::vector<HalfRows>& lowerHalf;
  const AlbedoLookup& albedo;
  int bands;
  uint64_t seed;
  float maxDistance;
  std::vector<char> twoSided;  // per Scene::meshes entry: bakesBackSide
  // Per Scene::meshes entry (at least one entry): kTwoSided, and kLit where its hits send light
  // (it has lower-order transfer). 32-bit: the vector classifications gather them.
  std::vector<uint32_t> meshFlags;
  // Per Scene::meshes entry with lower-order transfer: where a lit hit's rows are (its corners:
  // cornerIndices).
  std::vector<LitMesh> litMeshes;
  // Per Scene::meshes entry: its triangles' corners, 3 per triangle, where it sends light; else null.
  // An array of their own, which the classification reads.
  std::vector<const uint32_t*> cornerIndices;
  bool allLitUniform = true;  // every instance in litMeshes has one colour: no ρ/π is looked up
  // The kernels of every phase, chosen once, when the tracer is built.
  ProbeKernels kernels = ProbeKernels::active();
  mutable TraceClock inEmbree;  // all threads' time inside Embree's calls (ProbeStats::traceSeconds)
  mutable TraceClock inGather;  // and inside the lit hits' gather, sumLit (ProbeStats::gatherSeconds)

  void intersect8(RayPacket8* p, size_t n) const {
    inEmbree.time([&] { rays.intersect8(p, n); });
  }
  void occluded(Ray* r, size_t n) const {
    inEmbree.time([&] { rays.occluded(r, n); });
  }

  // Traces `n` sphere directions from x. full = reset acc, then accumulate M and moments;
  // otherwise only count rays and back faces into acc (the inside test). False when an
  // interrupt was requested before it finished (polled per stream of rays, so a probe with
  // millions of samples still stops at once); acc is then incomplete.
  bool trace(const glm::vec3& x, uint32_t n, uint64_t stream, bool full, ProbeAccum& acc) const;

  // M += Σ y gᵀ over a group's lit hits, g = ρ/π · t(h), chunk by chunk (kChunk hits summed in
  // float, then added to M), reading the hits from the classification's lists and prefetching
  // their rows a few hits ahead: with g and its products in registers where the kernels have a
  // listed kernel (AVX-512 up to 3 bands), else g of a chunk into rows.gHit, then its products
  // (lit_hits.cpp).
  void sumLit(StreamRows& rows, uint32_t hits, double* indirect) const;

 private:
  // ρ/π of each of a group's lit hits into rows.rho: looked up (AlbedoLookup::atMany) on textured
  // or vertex-coloured instances, 1 on an instance of one colour (its rows hold ρ/π · t already).
  // Returns how many were looked up.
  uint32_t lookUpAlbedo(StreamRows& rows, uint32_t hits) const;
  // One stream of the full set: its rays' SH values, classification and M⁰; the group's lit hits
  // (nLit so far) gathered after its last stream.
  void addStream(const RayPacket8* batch, uint32_t first, uint32_t count, uint32_t n, uint32_t& nLit,
                 ProbeAccum& acc) const;
  // M⁰ += Σ y yᵀ of the stream's escaped rays, into acc.direct's upper triangle.
  void addDirect(const float* groupYs, const int32_t* escapedLanes, uint32_t count, ProbeAccum& acc) const;
};

// Sets up a tracer built with the scene, its BVH, storage for the lit instances' rows and the
// albedo lookup: which instances bake their back sides, the lit instances' rows as halves from
// lowerOrder (SurfaceTransfer::perMeshLowerOrder; empty: no lit instance), and the flags the
// classification reads.
void prepare(Tracer& tracer, const std::vector<std::vector<glm::vec3>>& lowerOrder, std::vector<HalfRows>& lowerHalf);

}  // namespace prt::bake::probe
