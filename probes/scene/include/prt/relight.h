// Relighting baked surface transfer on the CPU: the reference every renderer is checked against.
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "prt/scene.h"
#include "prt/sh.h"

namespace prt {

/// Exitant radiance of every vertex of every baked instance, L_o = (albedo/π)·(transfer·light).
/// `light` is truncated or zero-padded to the scene's bands. Instances without transfer
/// (receivers) get an empty vector. Throws prt::Error if the scene holds no transfer.
std::vector<std::vector<glm::vec3>> relightVertices(const Scene& scene, const sh::ShRgb& light);
/// The same for the back side of double-sided instances (MeshInstance::transferBack): the
/// radiance leaving the side opposite the normal. Instances without back transfer get an
/// empty vector.
std::vector<std::vector<glm::vec3>> relightBackVertices(const Scene& scene, const sh::ShRgb& light);

}  // namespace prt
