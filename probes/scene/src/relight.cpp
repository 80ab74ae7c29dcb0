#include "prt/relight.h"

#include <cmath>

#include "prt/error.h"
#include "prt/math.h"

namespace prt {

namespace {

// L_o = (ρ/π) E per vertex of one side, E = t · light, and with a split (`directLight` given,
// relightVerticesSplit) E = t · light − t⁰ · directLight + directIrradiance, `light` then
// holding the direct lights' SH too.
std::vector<std::vector<glm::vec3>> relightSide(const Scene& scene, const sh::ShRgb& light, bool back,
                                                const sh::ShRgb* directLight = nullptr,
                                                const std::vector<std::vector<glm::vec3>>* directIrradiance = nullptr) {
  if (scene.transferBands <= 0) throw Error(cat(scene.path, ": holds no baked transfer (run prt bake first)"));
  const sh::ShRgb l = sh::resize(light, scene.transferBands);
  const sh::ShRgb d = directLight ? sh::resize(*directLight, scene.transferBands) : sh::ShRgb();
  const int n2 = l.size();
  std::vector<std::vector<glm::vec3>> out(scene.meshes.size());
  for (size_t k = 0; k < scene.meshes.size(); ++k) {
    const MeshInstance& m = scene.meshes[k];
    const std::vector<glm::vec3>& t = back ? m.transferBack : m.transfer;
    if (t.empty()) continue;
    PRT_CHECK_EQ(t.size(), m.vertexCount() * size_t(n2));
    if (directIrradiance) PRT_CHECK_EQ((*directIrradiance)[k].size(), m.vertexCount());
    out[k].resize(m.vertexCount());
    for (size_t v = 0; v < m.vertexCount(); ++v) {
      glm::vec3 e = sh::dot(t.data() + v * size_t(n2), l.c.data(), n2);
      if (directLight) {  // minus the direct lights' direct part, plus their exact light
        const float* t0 = m.directTransferOf(v, scene.transferBands, back);
        for (int i = 0; i < n2; ++i) e -= t0[i] * d.c[size_t(i)];
        e += (*directIrradiance)[k][v];
      }
      out[k][v] = diffuseAlbedoAtVertex(scene, m, uint32_t(v)) * e * float(1.0 / kPi);
    }
  }
  return out;
}

}  // namespace

bool hasDirectTransfer(const Scene& scene) {
  bool any = false;
  for (const MeshInstance& m : scene.meshes) {
    if (m.transfer.empty()) continue;
    any = true;
    if (!m.hasDirectTransfer() || m.hasBackTransfer() != !m.transferDirectBack.empty()) return false;
  }
  return any;
}

std::vector<std::vector<glm::vec3>> relightVerticesSplit(const Scene& scene, const sh::ShRgb& light,
                                                         const sh::ShRgb& directLight,
                                                         const std::vector<std::vector<glm::vec3>>& directIrradiance,
                                                         bool back) {
  if (scene.transferBands <= 0) throw Error(cat(scene.path, ": holds no baked transfer (run prt bake first)"));
  if (!hasDirectTransfer(scene))
    throw Error(cat(scene.path,
                    ": baked before prt kept the direct part apart (no _PRT_SH_DIRECT_ attributes): "
                    "bake it again to light suns exactly"));
  PRT_CHECK_EQ(directIrradiance.size(), scene.meshes.size());
  // t · (l + d) − t⁰ · d: the whole transfer sees both, minus the direct lights' direct part.
  sh::ShRgb all = sh::resize(light, scene.transferBands);
  all += sh::resize(directLight, scene.transferBands);
  return relightSide(scene, all, back, &directLight, &directIrradiance);
}

std::vector<std::vector<glm::vec3>> relightVertices(const Scene& scene, const sh::ShRgb& light) {
  return relightSide(scene, light, false);
}

std::vector<std::vector<glm::vec3>> relightBackVertices(const Scene& scene, const sh::ShRgb& light) {
  return relightSide(scene, light, true);
}

}  // namespace prt
