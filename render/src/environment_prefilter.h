// The environment's light prefiltered for glossy reflection (private header of render/;
// docs/render.md, "Materials"): the split sum's first factor (Karis 2013; Filament's libs/ibl),
// computed once per map on the CPU.
//
// Level k of the result holds, for every direction r, the map's radiance averaged over the GGX
// lobe of roughness r_k = k / (levels − 1) around r, with n = v = r (the split sum's assumption):
//   L_k(r) = Σ_i L(l_i)(n·l_i) / Σ_i (n·l_i),  l_i = 2(r·h_i)h_i − r,  h_i ~ D(h)(n·h)
// (Karis 2013, "Image based lighting", the n·l weighting). Each sample reads the source's box mip
// chain at the level whose texel matches the sample's share of the lobe, lod = ½ log2(Ω_s/Ω_p) + 1,
// Ω_s = 1/(N·pdf(l)), Ω_p the source texel's solid angle (Colbert and Křivánek, GPU Gems 3,
// ch. 20, "filtered importance sampling"): few samples, no fireflies. Level 0 (the mirror) is the
// map itself, averaged down to the level's size. Level k is (W₀ >> k) × (H₀ >> k), the texture's
// mip level k, so that one trilinear lookup at lod = roughness · (levels − 1) blends two
// neighbouring roughnesses.
#pragma once

#include <vector>

#include "prt/image.h"

namespace prt::render {

/// Levels of the prefiltered map (roughness 0, 0.2, ..., 1), the GGX samples per texel, and
/// level 0's width W₀. W₀ is fixed, whatever the map's size: the roughest level (W₀/32 × W₀/64,
/// 16 × 8) must still hold a smooth function of direction to 1% (an equirectangular map of 4 × 2
/// texels holds a linear one to 10%: test MaterialRender.PrefilteredMapIsTheLobeAverage).
constexpr int kPrefilterLevels = 6, kPrefilterSamples = 96, kPrefilterWidth = 512;

/// The prefiltered levels of an equirectangular map (prt/light.h's orientation): level 0
/// W₀ × W₀/2, level k half the previous. Deterministic (Hammersley points).
std::vector<ImageRgb> prefilterEnvironment(const ImageRgb& map, int levels = kPrefilterLevels,
                                           int samples = kPrefilterSamples);

/// The radiance of one prefiltered level towards unit direction d, bilinear as a GL_LINEAR
/// texture with GL_REPEAT in s and GL_CLAMP_TO_EDGE in t reads it (the tests' CPU reference).
glm::dvec3 samplePrefiltered(const std::vector<ImageRgb>& levels, double lod, const glm::dvec3& d);

}  // namespace prt::render
