// Tangent frames for normal maps: MikkTSpace (Morten S. Mikkelsen, "Simulation of Wrinkled
// Surfaces Revisited", 2008, and his reference implementation mikktspace.c), which the glTF 2.0
// specification prescribes where a primitive with a normal texture has no TANGENT ("client
// implementations SHOULD calculate tangents using default MikkTSpace algorithms").
//
// What this implementation does, step by step as mikktspace.c does it:
//   1. Vertices are identified by position, normal and texture coordinate (exact equality), so
//      copies of one vertex share a frame.
//   2. Per triangle, the tangent and bitangent directions from the texture coordinates'
//      derivatives (vOs, vOt), normalised and flipped by the sign of the triangle's signed area
//      in texture space, so the tangent points along +u whatever the winding; that sign is the
//      triangle's orientation (handedness).
//   3. Per corner, vOs projected onto the plane of the vertex normal, weighted by the corner's
//      angle (between the edges, projected likewise).
//   4. Per vertex and orientation, the weighted sum normalised. A vertex met by triangles of
//      both orientations (a mirrored seam sharing one vertex) can hold one frame in glTF: the
//      orientation of larger total angle wins.
//   5. A vertex whose every triangle has degenerate texture coordinates (zero area in texture
//      space) or zero area gets a fallback frame: a unit vector orthogonal to the normal
//      (Duff et al. 2017's basis), handedness +1, and is counted.
// Not done: mikktspace.c's grouping of a vertex's triangles into connected fans (step 4 joins
// all triangles of one orientation at a vertex, the same wherever the fans are connected) and
// its spreading of neighbours' frames into degenerate triangles (step 5 falls back instead).
//
// glTF's texture v points down the image; MikkTSpace's up. The derivatives use (u, 1 − v), so
// for the usual mapping (u along the surface's right, v down the image, seen from the normal's
// side) the handedness is +1 and the bitangent w · (n × t) points up the image (−v), as glTF's
// normal maps (+Y up) expect.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

namespace prt {

struct TangentResult {
  std::vector<glm::vec4> tangents;  // per vertex: xyz unit, orthogonal to the normal; w = ±1
  size_t degenerateVertices = 0;    // vertices given the fallback frame (step 5)
};

/// MikkTSpace tangents for a triangle list (3 indices per triangle). normals unit, one per
/// position, uvs one per position (glTF convention). Never NaN: non-finite or zero inputs give
/// the fallback frame.
TangentResult generateTangents(const std::vector<glm::vec3>& positions, const std::vector<glm::vec3>& normals,
                               const std::vector<glm::vec2>& uvs, const std::vector<uint32_t>& indices);

/// A unit vector orthogonal to unit n (Duff et al., "Building an Orthonormal Basis, Revisited",
/// JCGT 2017): the fallback tangent.
glm::vec3 anyTangent(const glm::vec3& n);

/// `tangent` made a unit vector orthogonal to n (Gram-Schmidt), or anyTangent(n) where it has no
/// component off n or is not finite; `ok` false in that case.
glm::vec3 orthogonalTangent(const glm::vec3& tangent, const glm::vec3& n, bool& ok);

}  // namespace prt
