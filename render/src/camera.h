// Camera maths without GL (private header of render/; the public part is in
// prt/render/renderer.h: cameraView, orbitFraming, orbitTarget, orbitView).
#pragma once

#include <glm/glm.hpp>

#include "prt/render/renderer.h"

namespace prt::render {

/// The projection of `c` for an image of aspect w / h: reversed depth (near → 1, far → 0) for
/// GL_ZERO_TO_ONE clip control; `orthoFar` is the far plane of an orthographic camera without one.
glm::dmat4 projection(const CameraView& c, double aspect, double orthoFar);

}  // namespace prt::render
