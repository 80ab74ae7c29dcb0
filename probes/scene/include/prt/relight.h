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

/// Exitant radiance with direct lights split off (docs/lights.md, "Direct lights"):
///   L_o = (albedo/π) · (t · light + (t − t⁰) · directLight + directIrradiance),
/// t⁰ the direct part of the transfer (MeshInstance::transferDirect, or transferDirectBack with
/// `back`), `directLight` the direct lights' SH (their bounced light), `directIrradiance[k][v]`
/// their exact shadowed irradiance at vertex v of instance k (RGB; prt::bake computes it with
/// shadow rays). Instances without transfer get an empty vector. Throws prt::Error if an
/// instance with transfer lacks the direct part (a bake from before prt kept it apart).
std::vector<std::vector<glm::vec3>> relightVerticesSplit(const Scene& scene, const sh::ShRgb& light,
                                                         const sh::ShRgb& directLight,
                                                         const std::vector<std::vector<glm::vec3>>& directIrradiance,
                                                         bool back = false);

/// Whether every instance with transfer also holds its direct part (on both sides where it has
/// two): what relightVerticesSplit and the renderer's direct lights need.
bool hasDirectTransfer(const Scene& scene);

}  // namespace prt
