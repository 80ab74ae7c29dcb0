// Lights inside the scene (point, spot, sphere, disk and rectangle lights) lit per pixel with a
// cube of shadow maps each (private header of render/; docs/render.md, "Lights inside the
// scene"): the constants of shaders/local_lighting.glsl and the cube faces' matrices. The pass
// that draws the maps and sets the uniforms is Renderer::Impl::drawLocalShadows
// (local_shading.cpp).
#pragma once

#include <array>

#include <glm/glm.hpp>

#include "prt/local_light.h"
#include "shader_sources.h"

namespace prt::render {

/// Texture unit of the lights' cube maps (after the material's and the environment's units).
constexpr int kLocalShadowUnit = 24;
/// Sides of the disk's area-matched polygon per pixel (probes/lights uses kDiskPolygonSides).
constexpr int kLocalDiskSides = 32;
/// Samples of the blocker search and of the filter.
constexpr int kLocalBlockerSamples = 8, kLocalFilterSamples = 16;
/// Largest search/filter radius, texels.
constexpr int kLocalMaxKernel = 32;
/// Texels a side of each cube face, at most (Frame::shadows.mapSize when smaller).
constexpr int kLocalMapSize = 512;

/// The GLSL type number of a light lit per pixel (0 point, 1 spot, 2 sphere, 3 disk, 4
/// rectangle); -1 for the types that are not (an emissive surface's triangles).
int localShaderType(const LocalLight& light);

/// World -> clip (GL_ZERO_TO_ONE depth) of the six 90° faces of a cube at `centre`, in the
/// order +X, −X, +Y, −Y, +Z, −Z (local_lighting.glsl picks the face by the largest component of
/// x − centre, and reads the depth back to the distance along that axis with near and far).
std::array<glm::dmat4, 6> cubeFaces(const glm::dvec3& centre, double nearPlane, double farPlane);

}  // namespace prt::render
