// Linear RGB float images: reading environment maps, writing frames.
#pragma once

#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace prt {

/// A linear RGB image, row-major, row 0 at the top.
struct ImageRgb {
  int width = 0;
  int height = 0;
  std::vector<glm::vec3> pixels;

  ImageRgb() = default;
  ImageRgb(int w, int h) : width(w), height(h), pixels(static_cast<size_t>(w) * h, glm::vec3(0)) {}
  glm::vec3& at(int x, int y) { return pixels[static_cast<size_t>(y) * width + x]; }
  const glm::vec3& at(int x, int y) const { return pixels[static_cast<size_t>(y) * width + x]; }
};

/// The image averaged down by a whole factor: each factor × factor block of pixels becomes its
/// mean (a box filter, the same sums in the same order every time). The sides must be multiples
/// of factor (prt::Error otherwise); factor 1 returns a copy.
ImageRgb downsampleBox(const ImageRgb& image, int factor);

/// Reads a linear HDR image: OpenEXR (.exr, R/G/B channels or Y) or Radiance (.hdr), chosen by
/// the file's magic bytes. Throws prt::Error naming the file on a missing, unreadable or
/// malformed file, absurd dimensions (> 32768 a side) or non-finite pixels.
ImageRgb loadHdrImage(const std::string& path);

/// OpenEXR compression, all lossless: Zip (deflate, 16 lines a block; smallest for smooth
/// renders, the slowest to write), Piz (wavelet; better on noisy images), None (fastest, largest).
enum class ExrCompression { None, Zip, Piz };

/// Writes float32 RGB OpenEXR, atomically (temporary file, then rename).
void writeExr(const std::string& path, const ImageRgb& image, ExrCompression compression = ExrCompression::Zip);

/// Writes 8-bit sRGB PNG, atomically: toneMapSrgb8(image, exposure).
void writePng(const std::string& path, const ImageRgb& image, float exposure = 0.0f);

/// sRGB transfer function (linear -> encoded) and its inverse, for one channel.
float linearToSrgb(float v);
float srgbToLinear(float v);

/// The 8-bit sRGB code of a linear value: v clamped to [0, 1] (NaN to 0), then
/// lround(linearToSrgb(v) · 255), exactly, from a table of the 255 thresholds between codes
/// (no pow per pixel).
unsigned char srgb8(float v);
/// Every pixel's value·2^exposure as srgb8, RGB interleaved, row 0 first: what PNGs, contact
/// sheets and videos hold.
std::vector<unsigned char> toneMapSrgb8(const ImageRgb& image, float exposure);

}  // namespace prt
