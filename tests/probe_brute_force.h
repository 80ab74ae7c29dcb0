// Independent brute-force irradiance at a point of a scene, for the probe tests (the probe bake's
// tests and the CLI's): its own random directions, traced with Embree, never the bake's sampling.
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/ray_scene.h"
#include "prt/bake/sampling.h"
#include "prt/math.h"
#include "prt/scene.h"
#include "prt/sh.h"

namespace prt::test {

// Irradiance at x for normal n by independent brute force: E(x, n) = ∫ L_in(x, ω) max(n·ω, 0) dω
// with L_in = sky where a ray escapes and ρ/π · (t_lower(h) · l) where it hits a front face (0 on
// a back face), from N cosine-weighted directions of std::mt19937 (not the bake's Sobol sequence,
// not its code path): E = (π/N) Σ L_in.
inline glm::dvec3 bruteIrradiance(const bake::RayScene& rays, const Scene& s,
                                  const std::vector<std::vector<glm::vec3>>& lower, float rho, const sh::ShRgb& sky,
                                  const glm::vec3& x, const glm::vec3& nrm, int N, std::mt19937& rng) {
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  const int n2 = int(sky.c.size());
  bake::Frame frame = bake::Frame::fromNormal(nrm);
  std::vector<bake::Ray> batch{size_t(N)};
  for (bake::Ray& r : batch) {
    r.org = x;
    r.dir = frame.toWorld(bake::sampleCosineHemisphere({uni(rng), uni(rng)}));
    r.tfar = 1e30f;
  }
  rays.intersect(batch.data(), batch.size(), false);
  glm::dvec3 sum(0.0);
  for (const bake::Ray& r : batch) {
    if (!r.hit()) {
      sum += glm::dvec3(sh::reconstruct(sky, r.dir));
    } else if (!r.backface() && !lower.empty() && !lower[r.mesh].empty()) {
      const MeshInstance& m = s.meshes[r.mesh];
      const uint32_t* ix = &m.indices[3 * size_t(r.tri)];
      glm::vec3 e(0.0f);
      for (int i = 0; i < n2; ++i) {
        glm::vec3 ti = (1.0f - r.u - r.v) * lower[r.mesh][ix[0] * n2 + i] + r.u * lower[r.mesh][ix[1] * n2 + i] +
                       r.v * lower[r.mesh][ix[2] * n2 + i];
        e += ti * sky.c[size_t(i)];
      }
      sum += glm::dvec3(rho / float(prt::kPi) * e);
    }
  }
  return prt::kPi * sum / double(N);
}

}  // namespace prt::test
