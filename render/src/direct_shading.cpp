// Direct lights per pixel with PCSS-filtered shadow maps (docs/render.md, "Direct lights and
// their shadows").
//
// For a direct light k (a cap of angular radius r around d, irradiance E_k on a surface facing
// it) a pixel at x with unit normal n receives
//   E_k · directCosineFactor_k(n) · visibleShare_k(x)
// directCosineFactor is light.cpp's closed form (Note 4 there) in float; visibleShare is read
// from an orthographic shadow map along d:
// 1. The map stores, per texel, the depth (metres along −d from the map's near plane) of the
//    nearest caster. A receiver at map position p (metres) and depth z is occluded along the
//    light's centre direction where the stored depth is smaller.
// 2. Blocker search (PCSS, Fernando 2005): any occluder of the cap lies between the near plane
//    and x, so within a disk of radius tan r · z around p. kBlockerSamples points of a Vogel
//    spiral over that disk find the blockers and their mean depth z_b. None: fully lit (1).
// 3. Filter: a ray from x towards d + δ (|δ| ≤ tan r, the cap seen in the tangent plane) meets
//    the blocker plane at lateral offset (z − z_b) δ, so the share of the cap that arrives is the
//    share of the disk of radius tan r · (z − z_b) whose map depth lies beyond the receiver:
//    kFilterSamples spiral points, each compared. Exact for a planar occluder parallel to the
//    map (the cap taken uniform over the disk, ignoring the cosine's variation across a cap of
//    at most 20°), the usual PCSS approximation otherwise. Every blocker-search sample blocked
//    (and the filter disk inside the searched one): fully shadowed (0).
// Comparisons are against the receiver's tangent plane, not its centre depth ("receiver plane
// depth bias", Isidoro 2006): at offset o the receiver lies at z + grad · o, grad = n_xy / |n_z|
// in light space (|n_z| floored at 0.02, 88.9°), less a bias of (1 + |grad|) texels for the nearest-texel
// quantisation. The spiral is turned per pixel by interleaved gradient noise (Jimenez 2014) of
// the pixel position: deterministic, and it turns the banding of a few samples into noise.
// 4. Over the pixel's square: a pixel is the mean over its square, so both disks are convolved
//    with the square mapped into the map (pixelFootprint): each sample adds an R2 point of the
//    square to its spiral point. A pixel across an edge sharper than a pixel gets its square's
//    share, not the 0 or 1 at its centre.
// 5. Samples on empty texels (nothing drawn there) lie on no surface and do not vote: every
//    sample on a surface blocked is fully shadowed, the filter's share is over those samples.
//
// Loops. llvmpipe (Mesa 22.3) runs a fragment shader on vectors of pixels and executes both sides
// of every branch for all of them (masked), but it leaves a loop once no pixel of the vector
// needs another pass (the test is at the loop's end: the body always runs once). So work that
// most pixels skip goes into a loop, not an if: the blocker search (skipped where the cap is
// below the horizon), the filter (most pixels need none) and the lights (one light costs one
// pass, not two). The loops step by the uniform uLoopStep (1): with a
// constant step Mesa's NIR can bound the trip count and unroll the loop into straight code,
// which llvmpipe then runs whole for every pixel (measured, docs/render.md "Cost").
#include "direct_shading.h"

#include "local_shading.h"
#include "prt/error.h"
#include "render_shaders.h"
#include "shader_sources.h"

namespace prt::render {

std::string directLightingGlsl() {
  return fillShader(shaders::kDirectLighting, {{"MAX_DIRECT", cat(kMaxDirectLights)},
                                               {"MAX_SHADOW_LAYERS", cat(kMaxDirectLights * kMaxCascades)},
                                               {"SHADOW_UNIT", cat(kShadowMapUnit)},
                                               {"BLOCKER_SAMPLES", cat(kBlockerSamples)},
                                               {"FILTER_SAMPLES", cat(kFilterSamples)},
                                               {"MAX_KERNEL", cat(kMaxKernelTexels)},
                                               {"MAX_LOCAL", cat(kMaxLocalLights)},
                                               {"LOCAL_UNIT", cat(kLocalShadowUnit)},
                                               {"DISK_SIDES", cat(kLocalDiskSides)},
                                               {"LOCAL_BLOCKER_SAMPLES", cat(kLocalBlockerSamples)},
                                               {"LOCAL_FILTER_SAMPLES", cat(kLocalFilterSamples)},
                                               {"LOCAL_MAX_KERNEL", cat(kLocalMaxKernel)}});
}

}  // namespace prt::render
