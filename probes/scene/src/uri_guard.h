// Where the files a glTF document refers to may come from, and the tinygltf file-system
// callbacks that enforce it. Free of tinygltf: the callbacks have the signatures of
// tinygltf::FsCallbacks but only standard types.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace prt::gltf {

// A .gltf/.glb and every file it refers to: tinygltf holds sizes in 32-bit fields (GLB
// lengths, its string loaders), so 4 GiB is its own limit.
constexpr uint64_t kMaxFileBytes = 0xFFFFFFFFull;

/// Where the files a glTF refers to may come from (buffers and images by URI). The scene's
/// folder, resolved through symbolic links, unless external URIs are allowed; nothing when
/// the document was read from memory.
struct UriGuard {
  std::string baseDir;                 // as tinygltf joins URIs to it ("" = read from memory)
  std::filesystem::path canonicalDir;  // the folder every file must lie in
  bool allowExternal = false;
  std::string refusal;             // first refused file, reported once parsing returns
  bool refusalIsExternal = false;  // ... refused for lying outside the folder (ExternalUriRefused)
};

/// The end of every refusal of a URI outside the scene's folder.
inline constexpr const char* kExternalRefused = "refused unless external URIs are allowed";

// tinygltf file-system callbacks: every file it opens passes the guard (tinygltf also looks
// in the working directory, and follows whatever path a URI spells).
bool guardedFileExists(const std::string& path, void* user);
std::string guardedExpandFilePath(const std::string& path, void* user);
bool guardedReadWholeFile(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user);
bool refuseWrite(std::string* err, const std::string&, const std::vector<unsigned char>&, void*);

/// Checks what tinygltf would trust: the nesting depth of the document and the URIs of
/// buffers and images. Syntax errors are left to tinygltf, which reports them.
void checkDocument(const std::string& path, const std::string& text, const UriGuard& guard);

}  // namespace prt::gltf
