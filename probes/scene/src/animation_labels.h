// Names of animation parts for messages, shared by the reader's messages
// (gltf_animation_read.cpp) and describeReceivers (animation.cpp).
#pragma once

#include <string>

#include "prt/animation.h"

namespace prt::detail {

/// "translation", "rotation" or "scale".
const char* pathName(AnimationPath p);
/// "node 3 'Box'" (the name only where the node has one).
std::string nodeLabel(const SceneAnimation& animation, int node);

}  // namespace prt::detail
