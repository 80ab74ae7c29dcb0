// An independent Embree 3 ceiling for the bake's rays: its own device and BVH, and every way
// Embree 3 offers to trace a batch of rays, each timed on the same rays, the fastest taken.
// It shares no code with prt's RayScene (bake/src/ray_scene.cpp), whose choices it judges: only
// the rays come from prt (the bake's own ray generators), so that both trace exactly the same.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cpu_clock.h"           // median
#include "prt/bake/ray_scene.h"  // bake::Ray: the rays as the bake generates them (plain data)
#include "prt/scene.h"

namespace prt::bench {

enum class RayKind { Occlusion, ClosestHit };

const char* kindName(RayKind kind);

/// How a rate is timed: wall clock, or the process's CPU time (cpu_clock.h).
enum class Timing { Wall, Cpu };

/// One way of tracing: its name and the rates of every round it was timed in.
struct ModeRate {
  std::string mode;
  std::vector<double> raysPerSecond[2];  // [Timing], one per round
  double best(Timing t) const;
  double median(Timing t) const;  // of its rounds
};

/// Every mode's rates for one kind of ray; the ceiling is the fastest mode's fastest round.
struct Ceiling {
  RayKind kind = RayKind::Occlusion;
  uint64_t rays = 0;  // rays traced per mode and round
  std::vector<ModeRate> modes;
  const ModeRate& bestMode(Timing t) const;
  double rate(Timing t) const { return bestMode(t).best(t); }
  /// The mode with the highest median over the rounds. The fastest mode of each round is the
  /// largest of many noisy timings, above what that mode, or any, typically does; this one is
  /// for ratios against the best mode's rate in the same round, with no such bias.
  const ModeRate& bestMedianMode(Timing t) const;
};

/// The ceiling, its best mode and every mode's best rate and range, per timing.
nlohmann::json toJson(const Ceiling& c);

/// Adds the rounds of `more` (the same modes, measured again) to `into`; `into` may be empty.
void appendRounds(Ceiling& into, const Ceiling& more);

/// The fastest mode's rate in round r alone (for ratios within one round).
double roundRate(const Ceiling& c, size_t r, Timing t);

class EmbreeCeiling {
 public:
  /// Builds a BVH of the scene's non-receiver instances on a device of its own, with the flags a
  /// watertight bake needs (robust traversal, high build quality). Partial occluders (cutouts,
  /// BLEND, transmission) are traced as opaque: the ceiling has no filter to call.
  explicit EmbreeCeiling(const Scene& scene);
  ~EmbreeCeiling();
  EmbreeCeiling(const EmbreeCeiling&) = delete;
  EmbreeCeiling& operator=(const EmbreeCeiling&) = delete;

  /// Times every mode on `rays` (tnear, tfar, origins and directions as given) in `rounds`
  /// rounds, the modes interleaved within a round so that a burst of load on a shared machine
  /// hits them alike. `group` consecutive rays share an origin (a vertex, a probe); the work is
  /// split into tasks of `grain` groups on the current TBB arena (its thread limit holds).
  /// Each mode's rays are laid out before its timer starts. Precondition: rays.size() is a
  /// multiple of group.
  Ceiling measure(const std::vector<bake::Ray>& rays, size_t group, size_t grain, RayKind kind, int rounds) const;

  /// Bounding-box diagonal of the traced geometry (as the bake's ray offsets use).
  float sceneExtent() const { return extent_; }
  size_t triangles() const { return triangles_; }
  double buildSeconds() const { return buildSeconds_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  float extent_ = 1.0f;
  size_t triangles_ = 0;
  double buildSeconds_ = 0.0;
};

}  // namespace prt::bench
