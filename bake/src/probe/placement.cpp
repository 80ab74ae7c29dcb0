// Where probes go (placement.h): the quick inside tests of the lattice, the region kept, the
// relocation candidates, and the public placement, settings check and lattice layout.
#include "placement.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <type_traits>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../stage_runner.h"
#include "prt/bake/ranks.h"
#include "prt/error.h"
#include "tracer.h"

namespace prt::bake::probe {

namespace {

// ---- Where probes go (ProbeSettings::region, docs/probes.md "Where probes go").
// A lattice point is free when its quick test (kProbeTestRays sphere directions, stream 2·idx)
// sees back faces for at most the inside threshold. Of the free points, Auto keeps those where
// a receiver can be: near a surface (a hit within kNearSpacings spacings) or surrounded (surfaces
// fill more than kOpenAirShare of the sphere around it: rooms, streets, the air over a ground),
// and their neighbours. It drops open air far from everything (the void around a floating
// level, the sky high above a town), where a receiver gets the unoccluded light: there the
// scene fills at most kOpenAirShare of the sphere, which bounds what that light gets wrong.
// A scene with no surface near any lattice point (an empty scene) keeps every free point.
// Inside keeps only sealed space: two neighbouring free points are joined when the segment
// between them hits nothing; free points on the lattice's boundary whose ray outwards along
// that axis escapes touch the outside; what the flood from them does not reach is sealed in by
// the scene's surfaces.
constexpr double kNearSpacings = 2.0;
constexpr double kOpenAirShare = 0.2;

// The free points of the lattice that the flood from outside (the comment above LatticeRegion) does not reach.
std::vector<uint8_t> sealedSpace(const Tracer& tracer, const ProbeGrid& grid, LatticeRegion& reg) {
  const glm::ivec3 dims = grid.dims;
  const size_t total = size_t(dims.x) * dims.y * dims.z;
  const size_t sy = size_t(dims.x), sz = size_t(dims.x) * dims.y;
  const size_t step[3] = {1, sy, sz};
  // Segments to the +x, +y, +z free neighbours, and outward rays of boundary points.
  std::vector<uint8_t> links(total, 0);  // bit a: joined to the +a neighbour; bit 3: touches the outside
  tbb::parallel_for(tbb::blocked_range<size_t>(0, total, 256), [&](const tbb::blocked_range<size_t>& r) {
    alignas(64) Ray batch[9];
    uint8_t bitOf[9];
    for (size_t idx = r.begin(); idx != r.end(); ++idx) {
      if (!reg.free[idx]) continue;
      const glm::ivec3 c = latticeCoord(dims, idx);
      const glm::vec3 x(grid.latticePosition(c));
      int n = 0;
      auto add = [&](int a, float sign, float tfar, uint8_t bit) {
        Ray& ray = batch[n];
        ray = Ray{};
        ray.org = x;
        ray.dir = glm::vec3(0.0f);
        ray.dir[a] = sign;
        ray.tfar = tfar;
        bitOf[n++] = bit;
      };
      for (int a = 0; a < 3; ++a) {
        if (c[a] + 1 < dims[a] && reg.free[idx + step[a]]) add(a, 1.0f, float(grid.spacing[a]), uint8_t(1u << a));
        if (c[a] == 0) add(a, -1.0f, std::numeric_limits<float>::infinity(), 8u);
        if (c[a] == dims[a] - 1) add(a, 1.0f, std::numeric_limits<float>::infinity(), 8u);
      }
      if (n == 0) continue;
      tracer.occluded(batch, size_t(n));
      for (int k = 0; k < n; ++k)
        if (!batch[k].occludedHit()) links[idx] |= bitOf[k];
    }
  });
  for (size_t idx = 0; idx < total; ++idx) {
    if (!reg.free[idx]) continue;
    const glm::ivec3 c = latticeCoord(dims, idx);
    for (int a = 0; a < 3; ++a)
      reg.rays += uint64_t(c[a] + 1 < dims[a] && reg.free[idx + step[a]]) + (c[a] == 0) + (c[a] == dims[a] - 1);
  }
  // The flood from the outside: sequential, in lattice order, the same for any thread count.
  std::vector<uint8_t> out(total, 0);
  std::vector<size_t> queue;
  for (size_t idx = 0; idx < total; ++idx)
    if (reg.free[idx] && (links[idx] & 8u)) {
      out[idx] = 1;
      queue.push_back(idx);
    }
  for (size_t head = 0; head < queue.size(); ++head) {
    const size_t idx = queue[head];
    const glm::ivec3 c = latticeCoord(dims, idx);
    for (int a = 0; a < 3; ++a) {
      if (c[a] + 1 < dims[a] && (links[idx] & (1u << a)) && !out[idx + step[a]]) {
        out[idx + step[a]] = 1;
        queue.push_back(idx + step[a]);
      }
      if (c[a] > 0 && (links[idx - step[a]] & (1u << a)) && !out[idx - step[a]]) {
        out[idx - step[a]] = 1;
        queue.push_back(idx - step[a]);
      }
    }
  }
  std::vector<uint8_t> sealed(total, 0);
  for (size_t idx = 0; idx < total; ++idx) {
    sealed[idx] = reg.free[idx] && !out[idx];
    reg.sealed += sealed[idx];
  }
  return sealed;
}

// Above the level: open sky straight up (+Y, glTF's up) and nothing within `height` straight
// down. Where a roofless level's walls surround a point, a receiver still stands on something:
// what lies higher above the ground than any receiver reaches is the void over the level.
bool aboveTheLevel(const Tracer& tracer, const glm::vec3& x, float height) {
  alignas(64) Ray batch[2];
  for (int k = 0; k < 2; ++k) {
    batch[k] = Ray{};
    batch[k].org = x;
    batch[k].dir = glm::vec3(0.0f, k == 0 ? 1.0f : -1.0f, 0.0f);
    batch[k].tfar = k == 0 ? std::numeric_limits<float>::infinity() : height;
  }
  tracer.occluded(batch, 2);
  return !batch[0].occludedHit() && !batch[1].occludedHit();
}

// Whether f(j) holds for one of the 26 neighbours j of lattice point idx inside the lattice
// (linear indices, as latticeCoord's), stopping at the first.
template <class F>
bool anyNeighbour(const glm::ivec3& dims, size_t idx, F&& f) {
  const size_t sy = size_t(dims.x), sz = size_t(dims.x) * dims.y;
  const glm::ivec3 c = latticeCoord(dims, idx);
  for (int d = 0; d < 27; ++d) {
    const glm::ivec3 q = c + glm::ivec3(d % 3 - 1, (d / 3) % 3 - 1, d / 9 - 1);
    if (d == 13 || glm::any(glm::lessThan(q, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(q, dims))) continue;
    if (f(size_t(q.x) + sy * size_t(q.y) + sz * size_t(q.z))) return true;
  }
  return false;
}

// What the rest of the classification reads of each point's quick test, besides LatticeRegion::free.
struct QuickTests {
  std::vector<uint8_t> wanted;  // free, and near a surface or enclosed
  std::vector<float> nearest;   // the quick test's nearest hit
  std::vector<uint8_t> high;    // surrounded, but above the level (aboveTheLevel)
  explicit QuickTests(size_t total) : wanted(total, 0), nearest(total, 0.0f), high(total, 0) {}
};

// The quick test of every lattice point this process tests (`shared`: its share of the MPI
// ranks'), into reg.free and tests. False when interrupted before they finished.
bool testLattice(const Tracer& tracer, const ProbeGrid& grid, const ProbeSettings& settings, bool shared,
                 LatticeRegion& reg, QuickTests& tests) {
  const glm::ivec3 dims = grid.dims;
  const size_t total = size_t(dims.x) * dims.y * dims.z;
  const float nearDistance = float(kNearSpacings * std::max({grid.spacing.x, grid.spacing.y, grid.spacing.z}));
  const bool autoRegion = settings.region == ProbeSettings::Region::Auto;
  Ranks& spread = ranks();
  std::atomic<bool> stopped{false};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, total, 256), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t idx = r.begin(); idx != r.end(); ++idx) {
      if (stopped.load(std::memory_order_relaxed)) return;
      if (shared && !spread.owns(idx)) continue;
      ProbeAccum test;
      const glm::vec3 x(grid.latticePosition(latticeCoord(dims, idx)));
      if (!tracer.trace(x, kProbeTestRays, 2 * idx, false, test)) {
        stopped = true;
        return;
      }
      reg.free[idx] = !insideGeometry(test, settings.insideThreshold);
      tests.nearest[idx] = test.nearest;
      const bool nearSurface = test.nearest <= nearDistance;
      bool surrounded = double(test.rays - test.escaped) > kOpenAirShare * double(test.rays);
      if (reg.free[idx] && !nearSurface && surrounded && settings.maxHeight > 0.0 && autoRegion &&
          aboveTheLevel(tracer, x, float(settings.maxHeight))) {
        surrounded = false;
        tests.high[idx] = 1;
      }
      tests.wanted[idx] = reg.free[idx] && (nearSurface || surrounded);
    }
  });
  return !stopped;
}

// MPI ranks (ranks.h) test their share of the points, point i on rank i mod N, and trade the
// outcomes (what the rest of the classification reads of a point), as refinement trades its
// points.
void tradeTests(size_t total, LatticeRegion& reg, QuickTests& tests) {
  Ranks& spread = ranks();
  struct Outcome {
    float nearest;
    uint8_t free, wanted, high, unused;
  };
  static_assert(sizeof(Outcome) == 8 && std::is_trivially_copyable_v<Outcome>);
  std::string mine;
  mine.reserve((total / size_t(spread.size()) + 1) * sizeof(Outcome));
  for (size_t idx = 0; idx < total; ++idx) {
    if (!spread.owns(idx)) continue;
    const Outcome o{tests.nearest[idx], reg.free[idx], tests.wanted[idx], tests.high[idx], 0};
    mine.append(reinterpret_cast<const char*>(&o), sizeof o);
  }
  const std::vector<std::string> all = spread.gather(std::move(mine), true);
  std::vector<size_t> at(all.size(), 0);
  for (size_t idx = 0; idx < total; ++idx) {
    const size_t from = idx % all.size();
    if (int(from) == spread.rank()) continue;
    if (at[from] + sizeof(Outcome) > all[from].size())
      throw Error(cat("rank exchange of the probe placement: rank ", from, " sent too few points"));
    Outcome o;
    std::memcpy(&o, all[from].data() + at[from], sizeof o);
    at[from] += sizeof o;
    tests.nearest[idx] = o.nearest;
    reg.free[idx] = o.free;
    tests.wanted[idx] = o.wanted;
    tests.high[idx] = o.high;
  }
}

// The free points the region keeps (ProbeSettings::region).
std::vector<uint8_t> keptPoints(const Tracer& tracer, const ProbeGrid& grid, const ProbeSettings& settings,
                                const QuickTests& tests, LatticeRegion& reg) {
  using Region = ProbeSettings::Region;
  const glm::ivec3 dims = grid.dims;
  const size_t total = reg.free.size();
  const bool anyWanted = std::find(tests.wanted.begin(), tests.wanted.end(), uint8_t(1)) != tests.wanted.end();
  const bool everywhere = settings.region == Region::Everywhere || (settings.region == Region::Auto && !anyWanted);
  if (everywhere) return reg.free;
  if (settings.region != Region::Auto) {
    reg.insideOnly = true;
    return sealedSpace(tracer, grid, reg);
  }
  std::vector<uint8_t> keep(total, 0);
  for (size_t idx = 0; idx < total; ++idx)
    keep[idx] =
        reg.free[idx] && (tests.wanted[idx] || anyNeighbour(dims, idx, [&](size_t j) { return tests.wanted[j] != 0; }));
  return keep;
}

// The points not baked: free points left out, and points in geometry that are not tried for
// relocation because they border only free points left out (and geometry), or lie deep in
// solid: no free neighbour and no surface within a spacing, so that no candidate (all within
// 0.52 spacing of it) can leave the solid it is in.
void markSkipped(const ProbeGrid& grid, const std::vector<uint8_t>& keep, const QuickTests& tests, LatticeRegion& reg) {
  const glm::ivec3 dims = grid.dims;
  const float solidDistance = float(std::max({grid.spacing.x, grid.spacing.y, grid.spacing.z}));
  for (size_t idx = 0; idx < reg.free.size(); ++idx) {
    if (reg.free[idx]) {
      reg.skip[idx] = !keep[idx];
      reg.outside += !keep[idx];
      reg.aboveLevel += !keep[idx] && tests.high[idx];
      continue;
    }
    const bool nearFree = anyNeighbour(dims, idx, [&](size_t j) { return reg.free[j] != 0; });
    const bool nearKept = anyNeighbour(dims, idx, [&](size_t j) { return keep[j] != 0; });
    reg.skip[idx] = nearFree ? !nearKept : tests.nearest[idx] > solidDistance;
  }
}

// Blocks of side³ lattice points, from the origin, holding a point marked in `near`.
uint64_t countBlocks(const glm::ivec3& dims, const std::vector<uint8_t>& near, int side) {
  const glm::ivec3 b = (dims + side - 1) / side;
  std::vector<uint8_t> held(size_t(b.x) * b.y * b.z, 0);
  for (size_t idx = 0; idx < near.size(); ++idx) {
    if (!near[idx]) continue;
    const glm::ivec3 c = latticeCoord(dims, idx) / side;
    held[size_t(c.x) + size_t(b.x) * (size_t(c.y) + size_t(b.y) * c.z)] = 1;
  }
  return uint64_t(std::count(held.begin(), held.end(), uint8_t(1)));
}

}  // namespace

LatticeRegion classifyLattice(const Tracer& tracer, const ProbeGrid& grid, const ProbeSettings& settings, bool alone) {
  const size_t total = size_t(grid.dims.x) * grid.dims.y * grid.dims.z;
  LatticeRegion reg;
  reg.free.assign(total, 0);
  reg.skip.assign(total, 0);
  reg.rays = uint64_t(total) * kProbeTestRays;
  QuickTests tests(total);
  // Shards, which run apart, each test the whole lattice.
  const bool shared = !alone && ranks().exchanges();
  if (!testLattice(tracer, grid, settings, shared, reg, tests)) {
    reg.interrupted = true;
    return reg;
  }
  if (shared) tradeTests(total, reg, tests);
  for (uint8_t f : reg.free) reg.freeCount += f;
  const std::vector<uint8_t> keep = keptPoints(tracer, grid, settings, tests, reg);
  markSkipped(grid, keep, tests, reg);
  return reg;
}

// Relocation candidates, in a fixed order, as fractions of the spacing: along the axes, then
// towards the corners; all inside the probe's cell.
std::vector<glm::dvec3> relocationCandidates() {
  std::vector<glm::dvec3> candidates;
  for (double f : {0.25, 0.45})
    for (int axis = 0; axis < 3; ++axis)
      for (double sgn : {1.0, -1.0}) {
        glm::dvec3 o(0.0);
        o[axis] = sgn * f;
        candidates.push_back(o);
      }
  for (int c = 0; c < 8; ++c)
    candidates.push_back(glm::dvec3(c & 1 ? 0.3 : -0.3, c & 2 ? 0.3 : -0.3, c & 4 ? 0.3 : -0.3));
  return candidates;
}

}  // namespace prt::bake::probe

namespace prt::bake {

using namespace probe;

ProbePlacement placeProbes(const Scene& scene, const ProbeSettings& settings) {
  validate(settings);
  const ThreadLimit threadLimit(settings.threads);
  ProbeGrid grid;
  glm::dvec3 lo, hi;
  probeBounds(settings, scene, lo, hi);
  layoutGrid(settings, lo, hi, grid);
  const RayScene rays(scene);
  const AlbedoLookup albedo(scene);
  std::vector<HalfRows> none;  // the placement's rays gather no light
  const double maxSpacing = std::max(grid.spacing.x, std::max(grid.spacing.y, grid.spacing.z));
  Tracer tracer{scene, rays, none, albedo, settings.bands, settings.seed, float(2.0 * maxSpacing), {}};
  prepare(tracer, {}, none);
  const LatticeRegion region = classifyLattice(tracer, grid, settings, true);
  if (region.interrupted) throw Interrupted("interrupted (probe placement)");

  const glm::ivec3 dims = grid.dims;
  const size_t total = size_t(dims.x) * dims.y * dims.z;
  ProbePlacement out;
  out.points = total;
  std::vector<uint8_t> near(total, 0);  // baked, or next to a baked point (as assembleGrid's active)
  for (size_t idx = 0; idx < total; ++idx) {
    out.baked += !region.skip[idx];
    near[idx] = !region.skip[idx] || anyNeighbour(dims, idx, [&](size_t j) { return !region.skip[j]; });
  }
  out.activeBound = uint64_t(std::count(near.begin(), near.end(), uint8_t(1)));
  out.leafBlocks = countBlocks(dims, near, 8);
  out.lowerBlocks = countBlocks(dims, near, 128);
  return out;
}

void validate(const ProbeSettings& s) {
  validateBands(s.bands);
  if (s.samples < 1 || s.samples > kMaxSamples)
    throw Error(cat("probe samples ", s.samples, ": must be between 1 and ", kMaxSamples));
  if (!(s.spacing >= 0.0) || !std::isfinite(s.spacing)) throw Error("probe spacing: must be a positive number");
  if (s.spacing == 0.0 && (s.dims.x < 1 || s.dims.y < 1 || s.dims.z < 1))
    throw Error("probe dims: give three positive counts (or a probe spacing)");
  if (s.spacing == 0.0 && double(s.dims.x) * s.dims.y * s.dims.z > 512.0 * 512 * 512)
    throw Error("probe dims: more than 512³ probes");
  if (s.threads < 0) throw Error(cat("threads ", s.threads, ": must be 0 (all cores) or more"));
  if (!(s.maxHeight >= 0.0) || !std::isfinite(s.maxHeight))
    throw Error(cat("probe height ", s.maxHeight, ": must be 0 (no limit) or a positive number"));
  if (s.boundsMin && s.boundsMax) {
    glm::dvec3 lo = *s.boundsMin, hi = *s.boundsMax;
    if (!(lo.x < hi.x && lo.y < hi.y && lo.z < hi.z) || !std::isfinite(lo.x + lo.y + lo.z + hi.x + hi.y + hi.z))
      throw Error("probe bounds: the minimum must be below the maximum on every axis");
    const glm::dvec3 size = hi - lo;
    const double largest = std::max({size.x, size.y, size.z});
    for (int a = 0; a < 3; ++a)
      if (size[a] < kFlatFraction * largest)
        throw Error(cat("probe bounds: the box is flat (", "xyz"[a], " extent ", size[a], " against ", largest,
                        "): give the probes a volume, at least ", kFlatFraction,
                        " of the largest extent on every axis"));
  }
}

void probeBounds(const ProbeSettings& s, const Scene& scene, glm::dvec3& lo, glm::dvec3& hi) {
  lo = s.boundsMin.value_or(glm::dvec3(scene.boundsMin));
  hi = s.boundsMax.value_or(glm::dvec3(scene.boundsMax));
  if (s.boundsMin) return;  // given bounds were checked by validate()
  const glm::dvec3 size = hi - lo;
  const double largest = std::max({size.x, size.y, size.z});
  if (!(largest > 0.0)) throw Error("the scene's bounds are a single point: give probe bounds");
  for (int a = 0; a < 3; ++a)
    if (size[a] < kFlatFraction * largest) {  // pad symmetrically: the scene may lie on either side
      const double mid = 0.5 * (lo[a] + hi[a]);
      lo[a] = mid - 0.5 * largest;
      hi[a] = mid + 0.5 * largest;
    }
}

void layoutGrid(const ProbeSettings& s, const glm::dvec3& lo, const glm::dvec3& hi, ProbeGrid& grid) {
  glm::dvec3 size = glm::max(hi - lo, glm::dvec3(1e-9));
  if (s.spacing > 0.0) {
    glm::dvec3 n = glm::ceil(size / s.spacing);
    if (n.x * n.y * n.z > 512.0 * 512 * 512)
      throw Error(cat("probe spacing ", s.spacing, ": gives ", n.x, "×", n.y, "×", n.z, " probes (at most 512³)"));
    grid.dims = glm::max(glm::ivec3(n), glm::ivec3(1));
    grid.spacing = glm::dvec3(s.spacing);
    // Centre the lattice on the bounds.
    glm::dvec3 span = glm::dvec3(grid.dims) * s.spacing;
    grid.origin = lo + (size - span) * 0.5 + 0.5 * s.spacing;
  } else {
    grid.dims = s.dims;
    grid.spacing = size / glm::dvec3(s.dims);
    grid.origin = lo + 0.5 * grid.spacing;
  }
}

}  // namespace prt::bake
