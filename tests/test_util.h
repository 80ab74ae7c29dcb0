// Small helpers shared by several test files.
#pragma once

#include <algorithm>
#include <array>
#include <exception>
#include <functional>
#include <string>

#include "prt/error.h"
#include "prt/probe_grid.h"

namespace prt::test {

/// The message of the prt::Error that f throws, or a marker that fails every check on it.
inline std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const prt::Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("<not a prt::Error: ") + e.what() + ">";
  }
  return "<no exception>";
}

/// A grid of `bands` bands with a valid probe at every lattice point and M = scale · I, distance
/// moments at twice the largest spacing with zero variance: the probes of an empty scene.
inline ProbeGrid identityProbeGrid(int bands, glm::ivec3 dims, glm::dvec3 origin, glm::dvec3 spacing,
                                   float scale = 1.0f) {
  ProbeGrid g;
  g.bands = bands;
  g.dims = dims;
  g.origin = origin;
  g.spacing = spacing;
  const float miss = float(2.0 * std::max({spacing.x, spacing.y, spacing.z}));
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) g.coord.emplace_back(x, y, z);
  const size_t count = g.coord.size();
  const int n2 = g.coeffs();
  g.transfer.assign(count * g.transferStride(), 0.0f);
  for (size_t p = 0; p < count; ++p)
    for (int j = 0; j < n2; ++j)
      for (int c = 0; c < 3; ++c) g.transfer[p * g.transferStride() + (size_t(j) * n2 + j) * 3 + c] = scale;
  g.validity.assign(count, 1.0f);
  g.offset.assign(count, glm::vec3(0.0f));
  g.skyVisibility.assign(count, 1.0f);
  std::array<glm::vec2, 6> m;
  m.fill(glm::vec2(miss, miss * miss));
  g.moments.assign(count, m);
  g.buildIndex();
  return g;
}

}  // namespace prt::test
