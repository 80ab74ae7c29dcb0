// The .glb container the writers (gltf_write.cpp) produce: new data staged in a buffer of its
// own, images embedded with their original bytes, every kept buffer view packed into one
// buffer, the file written atomically. Private to prt::scene.
#pragma once

#include <cstddef>
#include <string>

#include "gltf_model.h"

namespace prt::gltf {

/// Appends `bytes` as a new buffer view of `buffer` (4-byte aligned, as float data needs).
int appendBufferView(tinygltf::Model& m, int buffer, const void* bytes, size_t size, int target);

/// The buffer new data goes to before packing; created on first use (`staging` < 0 until then).
int stagingBuffer(tinygltf::Model& m, int& staging);

/// Embeds the images, packs one buffer and writes `m` as a .glb at `outPath`, atomically.
/// `g` names the input in messages.
void writeGlb(const Gltf& g, tinygltf::Model& m, int& staging, const std::string& outPath);

}  // namespace prt::gltf
