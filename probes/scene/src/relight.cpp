#include "prt/relight.h"

#include <cmath>

#include "prt/error.h"
#include "prt/math.h"

namespace prt {

namespace {

std::vector<std::vector<glm::vec3>> relightSide(const Scene& scene, const sh::ShRgb& light, bool back) {
  if (scene.transferBands <= 0)
    throw Error(cat(scene.path, ": holds no baked transfer (run prt bake first)"));
  const sh::ShRgb l = sh::resize(light, scene.transferBands);
  const int n2 = l.size();
  std::vector<std::vector<glm::vec3>> out(scene.meshes.size());
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    const std::vector<glm::vec3>& t = back ? m.transferBack : m.transfer;
    if (t.empty()) continue;
    PRT_CHECK_EQ(t.size(), m.vertexCount() * size_t(n2));
    out[k].resize(m.vertexCount());
    for (size_t v = 0; v < m.vertexCount(); ++v) {
      glm::vec3 e = sh::dot(t.data() + v * size_t(n2), l.c.data(), n2);
      out[k][v] = albedoAtVertex(scene, m, uint32_t(v)) * e * float(1.0 / kPi);
    }
  }
  return out;
}

}  // namespace

std::vector<std::vector<glm::vec3>> relightVertices(const Scene& scene, const sh::ShRgb& light) {
  return relightSide(scene, light, false);
}

std::vector<std::vector<glm::vec3>> relightBackVertices(const Scene& scene, const sh::ShRgb& light) {
  return relightSide(scene, light, true);
}

}  // namespace prt
