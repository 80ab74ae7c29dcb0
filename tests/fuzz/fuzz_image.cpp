// libFuzzer target: HDR images (OpenEXR and Radiance .hdr, picked by magic bytes) through
// loadHdrImage. Any outcome but an image or a prt::Error is a bug (docs/robustness.md).
#include <cmath>

#include "fuzz_file.h"
#include "prt/error.h"
#include "prt/image.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static prt::fuzz::MemoryFile file("fuzz_image");
  try {
    prt::ImageRgb image = prt::loadHdrImage(file.set(data, size));
    // What the loader promises: the stated size, finite pixels.
    if (image.pixels.size() != size_t(image.width) * size_t(image.height)) __builtin_trap();
    for (const auto& p : image.pixels)
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) __builtin_trap();
  } catch (const prt::Error&) {}
  return 0;
}
