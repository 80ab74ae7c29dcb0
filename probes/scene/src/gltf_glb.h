// The container the writers (gltf_write.cpp, gltf_write_lit.cpp) produce: new data staged in a
// buffer of its own, images embedded with their original bytes, every kept buffer view packed
// into one buffer, the file (.glb, or .gltf) written atomically. Private to prt::scene.
#pragma once

#include <cstddef>
#include <string>

#include "gltf_model.h"

namespace prt::gltf {

/// Appends `bytes` as a new buffer view of `buffer` (4-byte aligned, as float data needs).
int appendBufferView(tinygltf::Model& m, int buffer, const void* bytes, size_t size, int target);

/// The buffer new data goes to before packing; created on first use (`staging` < 0 until then).
int stagingBuffer(tinygltf::Model& m, int& staging);

/// Writes `m` at `outPath` atomically, images embedded, every buffer packed into one and each
/// accessor's min and max its data's exact bounds: a .glb, or, where `outPath` ends in .gltf,
/// glTF JSON with the buffer as a data: URI. A perspective camera's zfar of 0 (an infinite
/// projection, as tinygltf and prt::Camera say it) is left out, as glTF says it. The file
/// passes the Khronos glTF Validator. `g` names the input in messages.
void writeSceneFile(const Gltf& g, tinygltf::Model& m, int& staging, const std::string& outPath);

}  // namespace prt::gltf
