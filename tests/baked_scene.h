// A scene baked in process, its transfer stored as `prt bake` stores it (3 bands): for the tests
// of what a baked scene is lit by (the bounce operator, its probe rows, buried vertices).
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/surface_bake.h"
#include "prt/scene.h"

namespace prt::test {

/// Bakes `s` in place with `samples` rays, `bounces` bounces and `seed`; returns the lower-order
/// transfer (t_{K−1}, one empty vector per instance unless `lowerOrder`).
inline std::vector<std::vector<glm::vec3>> bakeInPlace(Scene& s, int samples, int bounces, uint64_t seed,
                                                       bool lowerOrder = false) {
  bake::BakeSettings bs;
  bs.samples = samples;
  bs.bounces = bounces;
  bs.seed = seed;
  bs.keepLowerOrder = lowerOrder;
  bake::SurfaceTransfer t = bake::bakeSurface(s, bs);
  bake::storeTransfer(s, std::move(t.perMesh), std::move(t.perMeshDirect));
  s.transferBands = bs.bands;
  if (t.perMeshLowerOrder.empty()) t.perMeshLowerOrder.assign(s.meshes.size(), {});
  return std::move(t.perMeshLowerOrder);
}

}  // namespace prt::test
