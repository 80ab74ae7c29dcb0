// The steps both glTF writers take: the input read again and made ready for per-instance
// vertex data, accessors added (gltf_write.cpp), and the edited model written as a file that
// the Khronos glTF Validator accepts (gltf_glb.h). writeBakedScene (gltf_write.cpp) and
// writeLitScene (gltf_write_lit.cpp) are these steps around their own edits. Private to
// prt::scene.
#pragma once

#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "gltf_glb.h"
#include "gltf_model.h"
#include "prt/scene.h"

namespace prt::gltf {

/// Loads `inputPath` again, checks that it still matches `scene`, and makes it ready to carry
/// per-instance vertex data: POSITION bounds, strips and fans as lists, one mesh per node, no
/// transfer attributes, split and refined primitives rewritten. New data goes to the staging
/// buffer (`staging`: -1 until the first use).
Gltf reloadForWriting(const std::string& inputPath, const Scene& scene, int& staging);

/// The primitive of the reloaded model that instance `inst` is (its node's own mesh).
tinygltf::Primitive& primitiveOf(tinygltf::Model& m, const MeshInstance& inst);

/// A float VEC3 accessor over `values`, stored in the staging buffer.
int addVec3Accessor(tinygltf::Model& m, int& staging, const std::vector<glm::vec3>& values, const std::string& name);

void addExtensionUsed(tinygltf::Model& m, const std::string& name);

}  // namespace prt::gltf
