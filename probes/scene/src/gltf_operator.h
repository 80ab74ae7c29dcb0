// The bounce operator's place in a baked glTF file (gltf_operator.cpp). Private to prt::scene.
#pragma once

#include <memory>

#include "gltf_model.h"
#include "prt/bounce_operator.h"
#include "prt/scene.h"

namespace prt::gltf {

/// The buffer view asset.extras.prt_operator names, or -1.
int operatorBufferView(const tinygltf::Model& m);
/// Points asset.extras.prt_operator at buffer view `view` (after the views are packed).
void setOperatorBufferView(tinygltf::Model& m, int view);
/// Removes asset.extras.prt_operator (its buffer view is then dropped by the packing).
void dropOperator(tinygltf::Model& m);
/// Stores `op` (its bytes in a new buffer view of the staging buffer).
void storeOperator(tinygltf::Model& m, int& staging, const BounceOperator& op);
/// The operator of a baked file, checked against `scene` (loaded from it); null when it has
/// none. Throws prt::Error naming the file and the part that is wrong.
std::shared_ptr<const BounceOperator> readOperator(const Gltf& g, const Scene& scene);

}  // namespace prt::gltf
