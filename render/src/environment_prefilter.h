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
// map itself, resampled to the level's size. Every level has the same size, a slice of one 3D
// texture; a lookup blends the two slices around roughness · (levels − 1).
//
// The levels are octahedral maps (Engelhardt and Dachsbacher 2008; Cigolle et al. 2014, "A
// Survey of Efficient Representations for Independent Unit Vectors"), folded about +Y: the
// upper hemisphere is the inner diamond |u'| + |v'| ≤ 1 (u' = 2u − 1, v' = 2v − 1), the lower
// one its four corners; a direction's coordinates cost the shader a sum of absolute values and a
// division, where the equirectangular layout costs two arc tangents (docs/render.md, "Cost of
// the materials"). The map is continuous inside the square; at its outer edge GL_CLAMP_TO_EDGE
// reads half a texel short of the mirrored neighbour.
#pragma once

#include <vector>

#include "prt/image.h"

namespace prt::render {

/// Levels of the prefiltered map (roughness 0, 0.2, ..., 1), the GGX samples per texel, and
/// the levels' width W (octahedral, W × W: texels of about 0.5°, finer than the lobe of roughness 0.2).
constexpr int kPrefilterLevels = 6, kPrefilterSamples = 64, kPrefilterWidth = 256;

/// The prefiltered levels of an equirectangular map (prt/light.h's orientation), each an
/// octahedral W × W map in the same frame. Deterministic (Hammersley points).
std::vector<ImageRgb> prefilterEnvironment(const ImageRgb& map, int levels = kPrefilterLevels,
                                           int samples = kPrefilterSamples);

/// The prefiltered radiance towards unit direction d at fractional level `lod`: the two levels
/// around it bilinear (as a GL_LINEAR texture with GL_CLAMP_TO_EDGE reads them) and blended
/// linearly, as material_shading.glsl does (the tests' CPU reference).
glm::dvec3 samplePrefiltered(const std::vector<ImageRgb>& levels, double lod, const glm::dvec3& d);

/// Octahedral coordinates in [0, 1]² of unit direction d, and the unit direction of (u, v): each
/// the other's inverse (material_shading.glsl's octahedralUv is the first).
glm::dvec2 octahedralUv(const glm::dvec3& d);
glm::dvec3 octahedralDirection(const glm::dvec2& uv);

}  // namespace prt::render
