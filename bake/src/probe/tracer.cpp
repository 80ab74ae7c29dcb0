// The per-probe estimator (tracer.h): a probe's rays stream by stream, each phase by the kernels
// the tracer was built with (probe_types.h).
#include "tracer.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "prt/bake/interrupt.h"
#include "prt/bake/surface_layout.h"
#include "prt/error.h"
#include "prt/math.h"
#include "prt/sh.h"

namespace prt::bake::probe {

namespace {

// A probe's accumulator started afresh for `bands`, keeping the matrices' storage.
void startProbe(ProbeAccum& acc, int bands) {
  const int n2 = bands * bands;
  acc.n2 = n2;
  acc.direct.assign(size_t(n2) * n2, 0.0);
  acc.indirect.assign(size_t(n2) * n2 * 3, 0.0);
  acc.rays = acc.backfaces = acc.escaped = acc.backTwoSided = 0;
  acc.nearest = std::numeric_limits<float>::infinity();
  acc.sumD = {};
  acc.sumD2 = {};
  acc.count = {};
  acc.stream.reset(bands);
}

// What a stream of `count` rays counted, into the probe's totals.
void addCounts(ProbeAccum& acc, const StreamTally& t, uint32_t count) {
  acc.rays += count;
  acc.backfaces += t.backs;
  acc.backTwoSided += t.backsTwoSided;
  acc.escaped += t.escapes;
  acc.nearest = std::min(acc.nearest, t.nearest);
}

// The instances' flags the classification reads (Tracer::meshFlags).
void setMeshFlags(Tracer& tracer) {
  const size_t n = tracer.scene.meshes.size();
  tracer.meshFlags.assign(std::max<size_t>(n, 1), 0);
  for (size_t k = 0; k < n; ++k)
    tracer.meshFlags[k] = uint32_t((tracer.twoSided[k] ? kTwoSided : 0) |
                                   (k < tracer.lowerHalf.size() && !tracer.lowerHalf[k].empty() ? kLit : 0));
}

// The lit instances' rows as halves (both sides' transfer where both are baked), and where a
// lit hit finds them (Tracer::litMeshes, cornerIndices).
void addLitRows(Tracer& tracer, const std::vector<std::vector<glm::vec3>>& lowerOrder,
                std::vector<HalfRows>& lowerHalf) {
  const Scene& scene = tracer.scene;
  const AlbedoLookup& albedo = tracer.albedo;
  const int n2 = tracer.bands * tracer.bands;
  if (!lowerOrder.empty()) PRT_CHECK_EQ(lowerOrder.size(), scene.meshes.size());
  lowerHalf.resize(lowerOrder.size());
  for (size_t k = 0; k < lowerOrder.size(); ++k) {
    if (lowerOrder[k].empty()) continue;
    const size_t rows = (tracer.twoSided[k] ? 2 : 1) * scene.meshes[k].vertexCount();
    PRT_CHECK_EQ(lowerOrder[k].size(), rows * size_t(n2));
    // ρ/π of an instance of one colour (AlbedoLookup::at's, as a lit hit's) folded into its
    // rows: a lit hit's light is then the rows' weighted sum alone (LitMesh).
    const glm::vec3 rhoPi = albedo.uniform[k] ? albedo.constant[k] * float(1.0 / kPi) : glm::vec3(1.0f);
    lowerHalf[k].assign(lowerOrder[k], rows, n2, rhoPi);
  }
  tracer.litMeshes.resize(scene.meshes.size());
  tracer.cornerIndices.assign(scene.meshes.size(), nullptr);
  for (size_t k = 0; k < lowerHalf.size(); ++k) {
    if (lowerHalf[k].empty()) continue;
    LitMesh& m = tracer.litMeshes[k];
    tracer.cornerIndices[k] = scene.meshes[k].indices.data();
    m.stride = lowerHalf[k].stride;
    m.rows = lowerHalf[k].row(0);
    m.backRows = tracer.twoSided[k] ? lowerHalf[k].row(scene.meshes[k].vertexCount()) : m.rows;
    m.uniform = albedo.uniform[k];
    tracer.allLitUniform = tracer.allLitUniform && m.uniform;
  }
}

}  // namespace

ProbeKernels ProbeKernels::active() {
  const Kernels k = activeKernels();
  return {kDirectionKernels.of(k), kClassifyKernels.of(k), kProductKernels.of(k), kLitHitKernels.of(k)};
}

void prepare(Tracer& tracer, const std::vector<std::vector<glm::vec3>>& lowerOrder, std::vector<HalfRows>& lowerHalf) {
  for (const MeshInstance& m : tracer.scene.meshes) tracer.twoSided.push_back(bakesBackSide(tracer.scene, m));
  addLitRows(tracer, lowerOrder, lowerHalf);
  setMeshFlags(tracer);
}

bool Tracer::trace(const glm::vec3& x, uint32_t n, uint64_t stream, bool full, ProbeAccum& acc) const {
  if (full) startProbe(acc, bands);
  const SphereSet set(seed, stream, kernels.directions);
  RayBuffer buffer;
  RayPacket8* batch = buffer.packets();
  uint32_t nLit = 0;  // the group's lit hits so far (acc.stream.hitMesh …)
  for (uint32_t first = 0; first < n; first += kStream) {
    if (interruptRequested()) return false;
    const uint32_t count = std::min<uint32_t>(kStream, n - first);
    if (first == 0)
      set.fill(batch, x, first, count);
    else  // the first stream's packets, all of them (it was the longest), from the same origin
      set.refill(batch, first, count);
    intersect8(batch, count);
    if (full)
      addStream(batch, first, count, n, nLit, acc);
    else  // the inside test: counts only
      addCounts(acc, kernels.classify.tally(batch, count, meshFlags.data()), count);
  }
  const int n2 = acc.n2;
  if (full)  // M⁰ is symmetric: its lower triangle from the upper
    for (int a = 0; a < n2; ++a)
      for (int b = 0; b < a; ++b) acc.direct[size_t(a) * n2 + b] = acc.direct[size_t(b) * n2 + a];
  return true;
}

void Tracer::addStream(const RayPacket8* batch, uint32_t first, uint32_t count, uint32_t n, uint32_t& nLit,
                       ProbeAccum& acc) const {
  const int n2 = bands * bands;
  StreamRows& rows = acc.stream;
  const uint32_t inGroup = first % kGroup;                 // the stream's first ray within its group
  float* groupYs = rows.ys.data() + size_t(inGroup) * n2;  // the stream's packets
  for (uint32_t q = 0; q < count; q += 8) {
    const RayPacket8& r = batch[q >> 3];
    sh::evaluate8(bands, r.dirX, r.dirY, r.dirZ, groupYs + size_t(q) * n2);
  }
  alignas(32) int32_t escapedLanes[kStream];  // per ray of the stream: −1 where it escaped, else 0
  StreamTally t{0, 0, 0, std::numeric_limits<float>::infinity()};
  const Classification c{meshFlags.data(),
                         cornerIndices.data(),
                         inGroup * uint32_t(n2),
                         uint32_t(n2),
                         maxDistance,
                         rows,
                         nLit,
                         escapedLanes,
                         acc};
  kernels.classify.classify(batch, count, c, t);
  addCounts(acc, t, count);
  addDirect(groupYs, escapedLanes, count, acc);
  // The indirect part of the group's lit hits, once its last stream is traced: M += Σ y gᵀ.
  if (inGroup + count == uint32_t(kGroup) || first + count == n) {
    if (nLit) inGather.time([&] { sumLit(rows, nLit, acc.indirect.data()); });
    nLit = 0;
  }
}

void Tracer::addDirect(const float* groupYs, const int32_t* escapedLanes, uint32_t count, ProbeAccum& acc) const {
  // Over the packets with an escaped ray: a packet whose rays all hit adds zeros, which leave
  // the sums as they are.
  const int n2 = acc.n2;
  uint8_t escapedPackets[kStream / 8];
  int nEscaped = 0;
  for (uint32_t q = 0; q < (count + 7) / 8; ++q) {
    const int32_t* e = escapedLanes + 8 * q;
    escapedPackets[nEscaped] = uint8_t(q);
    nEscaped += (e[0] | e[1] | e[2] | e[3] | e[4] | e[5] | e[6] | e[7]) != 0;
  }
  if (!nEscaped) return;
  float* sums = acc.stream.directSums.data();
  kernels.products.directSums(groupYs, escapedLanes, escapedPackets, nEscaped, n2, sums);
  // The stream's M⁰ sums into the double matrix's upper triangle, lane by lane in order.
  for (int a = 0, p = 0; a < n2; ++a)
    for (int b = a; b < n2; ++b, ++p) {
      const float* lane = &sums[size_t(8 * p)];
      double sum = 0.0;
      for (int l = 0; l < 8; ++l) sum += double(lane[l]);
      acc.direct[size_t(a) * n2 + b] += sum;
    }
}

}  // namespace prt::bake::probe
