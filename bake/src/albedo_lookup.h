// Base colour at ray hits, with a fast path for instances of uniform colour.
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "prt/scene.h"

namespace prt::bake {

struct AlbedoLookup {
  const Scene& scene;
  std::vector<uint8_t> uniform;      // per instance: no texture, no vertex colours
  std::vector<glm::vec3> constant;   // its colour when uniform

  explicit AlbedoLookup(const Scene& s) : scene(s) {
    for (const MeshInstance& m : s.meshes) {
      bool textured = m.material >= 0 && s.materials[size_t(m.material)].baseColorTexture >= 0;
      bool uni = !textured && m.colors.empty();
      uniform.push_back(uni);
      constant.push_back(uni && m.triangleCount() ? albedoAtVertex(s, m, m.indices[0]) : glm::vec3(0));
    }
  }
  glm::vec3 at(uint32_t mesh, uint32_t localTri, float b1, float b2) const {
    if (uniform[mesh]) return constant[mesh];
    return albedoAt(scene, scene.meshes[mesh], localTri, b1, b2);
  }
};

}  // namespace prt::bake
