// WebP decoding for base colour textures (image_webp.h).
#include "image_webp.h"

#include <webp/decode.h>

#include <cstring>

#include "prt/error.h"

namespace prt::gltf {

bool isWebp(const std::vector<unsigned char>& bytes) {
  return bytes.size() >= 12 && std::memcmp(bytes.data(), "RIFF", 4) == 0 &&
         std::memcmp(bytes.data() + 8, "WEBP", 4) == 0;
}

Rgba8 decodeWebp(const std::vector<unsigned char>& bytes, int64_t maxSide, int64_t maxTexels, std::string& error) {
  Rgba8 out;
  int w = 0, h = 0;
  if (!WebPGetInfo(bytes.data(), bytes.size(), &w, &h)) {
    error = "not a valid WebP image (bad header)";
    return out;
  }
  if (w <= 0 || h <= 0 || w > maxSide || h > maxSide || int64_t(w) * h > maxTexels) {
    error = cat("image ", w, "x", h, " is too large (at most ", maxSide, " a side, ", maxTexels, " texels)");
    return out;
  }
  const size_t stride = size_t(w) * 4;
  std::vector<unsigned char> texels(stride * size_t(h));
  if (!WebPDecodeRGBAInto(bytes.data(), bytes.size(), texels.data(), texels.size(), int(stride))) {
    error = "cannot decode the WebP image (corrupt data)";
    return out;
  }
  out.width = w;
  out.height = h;
  out.texels = std::move(texels);
  return out;
}

}  // namespace prt::gltf
