// Direct lights (suns, small disks) lit per pixel with shadow maps (private header of render/;
// docs/render.md, "Direct lights and their shadows"): the GLSL of the per-pixel term
//   E_direct(x, n) = Σ_k E_k · directCosineFactor_k(n) · visibleShare_k(x)
// (shaders/direct_lighting.glsl: directCosineFactor ported from probes/lights/src/light.cpp,
// visibleShare from PCSS-filtered shadow maps). The maps themselves: shadow_pass.h.
#pragma once

#include <string>

#include "prt/render/renderer.h"

namespace prt::render {

/// Texture unit of the shadow maps (0: base colour, 1–3: probes, 4–11: background maps).
constexpr int kShadowMapUnit = 12;
/// Samples of the blocker search and of the filter (a Vogel spiral turned per pixel).
constexpr int kBlockerSamples = 8, kFilterSamples = 16;
/// Largest search/filter radius, in shadow-map texels: wider penumbrae are sampled this wide.
constexpr int kMaxKernelTexels = 48;

/// GLSL (fragment stage) declaring the direct lights' uniforms, the input vWorldPixel (the
/// world position interpolated at the pixel's centre, which the vertex stage must write),
///   void pixelFootprint(out vec3 dxW, out vec3 dyW)
/// (to call at the top of main: the world position's change across the pixel) and
///   vec3 directIrradiance(vec3 x, vec3 n, vec3 dxW, vec3 dyW)
/// = Σ_k E_k · directCosineFactor_k(n) · visibleShare_k(x) over the pixel's square, the last 1
/// when uShadowed is 0.
std::string directLightingGlsl();

}  // namespace prt::render
