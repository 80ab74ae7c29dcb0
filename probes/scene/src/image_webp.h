// WebP images (EXT_texture_webp), decoded with libwebp where stb_image decodes PNG and JPEG.
// Free of tinygltf and of libwebp's types.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace prt::gltf {

constexpr const char* kTextureWebp = "EXT_texture_webp";

/// True when `bytes` start with a WebP container header (RIFF....WEBP).
bool isWebp(const std::vector<unsigned char>& bytes);

/// A decoded image: 8-bit RGBA, rows top to bottom (as stb_image returns them).
struct Rgba8 {
  int width = 0;
  int height = 0;
  std::vector<unsigned char> texels;
};

/// Decodes WebP `bytes` into RGBA (opaque images get alpha 255). The header's dimensions are
/// checked against `maxSide` and `maxTexels` before anything is allocated. On failure returns
/// an empty image and says why in `error`.
Rgba8 decodeWebp(const std::vector<unsigned char>& bytes, int64_t maxSide, int64_t maxTexels, std::string& error);

}  // namespace prt::gltf
