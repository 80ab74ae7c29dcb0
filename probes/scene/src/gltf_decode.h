// Compressed glTF geometry, decoded before tinygltf sees the document: KHR_draco_mesh_compression
// (Draco primitives) and EXT_meshopt_compression (meshopt buffer views). Debian's tinygltf is
// built without Draco and knows neither extension (it fails on the accessors Draco leaves
// without a buffer view, and tries to read meshopt's fallback buffer, which has no URI), so the
// document is rewritten into an ordinary one: a GLB whose one buffer holds the original
// buffers and the decoded data, every buffer view rebased onto it, both extensions gone.
// Free of tinygltf: it works on the JSON (nlohmann) and the bytes.
#pragma once

#include <optional>
#include <string>

#include "uri_guard.h"

namespace prt::gltf {

constexpr const char* kDraco = "KHR_draco_mesh_compression";
constexpr const char* kMeshopt = "EXT_meshopt_compression";
constexpr const char* kMeshQuantization = "KHR_mesh_quantization";

/// The document `bytes` (.gltf text, or .glb when `binary`) with its Draco primitives and meshopt
/// buffer views decoded and its data:image/webp URIs moved into buffer views, as GLB bytes;
/// nothing when it has none of them (the bytes are then parsed as they are). Buffers given by URI are read through
/// `guard`. Throws prt::Error
/// naming the file and the mesh / primitive or buffer view whose stream is corrupt.
std::optional<std::string> decodeCompressed(const std::string& path, const std::string& bytes, bool binary,
                                            UriGuard& guard);

}  // namespace prt::gltf
