// A linked GL program and the locations of the uniforms the renderer sets (private header of
// render/), after Filament's OpenGLProgram: compile, link, look the uniforms up once.
#pragma once

#include <string>

#include "gl_objects.h"

namespace prt::render {

/// A program and its uniforms' locations (-1 where the program has no such uniform).
struct Program {
  GlProgram id;
  GLint viewProj = -1, model = -1, normalMatrix = -1, light = -1, baseColor = -1, origin = -1, spacing = -1, dims = -1,
        nearZero = -1, alphaCutoff = -1, opacity = -1;
  // DIRECT variants (direct_shading.h)
  GLint directSh = -1, directCount = -1, directDir = -1, directIrradiance = -1, shadowed = -1, cascades = -1,
        cascadeFar = -1, viewOrigin = -1, viewForward = -1, shadowSize = -1, shadowMatrix = -1, shadowParams = -1,
        loopStep = -1;
  // MATERIAL variants (material_pass.cpp)
  GLint material = -1, emissive = -1, specularColor = -1, diffuseScale = -1, slots = -1, vertexInputs = -1, eye = -1,
        envWorldToMap = -1, envScale = -1, envUniform = -1, envMaxLod = -1, envOn = -1, skySh = -1;
};

/// Throws prt::Error naming `where` if the GL has an error pending.
void checkGlError(const GlFunctions& gl, const char* where);

/// Compiles and links a vertex and a fragment shader; throws prt::Error with the GL's log
/// ("GL: <what> vertex shader does not compile: ...") when one fails.
Program linkProgram(const GlFunctions& gl, const std::string& vertexSource, const std::string& fragmentSource,
                    const char* what);

}  // namespace prt::render
