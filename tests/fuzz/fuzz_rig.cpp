// libFuzzer target: light rigs (JSON, docs/lights.md) through parseLightRigFromMemory, then
// what a rig promises once it parses: evaluate() at frames in and around its keys, on 1, 3 and
// 8 bands, gives finite SH, and throws nothing (a NaN or an infinity aborts, so the fuzzer
// keeps the input). Environment lights use maps in memory (no file is ever read): "sky.hdr"
// (smooth, with a bright spot), "one.exr" (a single pixel) and "hot.exr" (every pixel near the
// largest radiance a rig allows, just under 1e30). docs/robustness.md tells how to run it.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "prt/error.h"
#include "prt/light_rig.h"

namespace {

prt::RigReadOptions options() {
  prt::RigReadOptions o;  // baseDir "": no files
  prt::ImageRgb sky(16, 8);
  for (int y = 0; y < sky.height; ++y)
    for (int x = 0; x < sky.width; ++x) sky.at(x, y) = glm::vec3(0.2f + 0.1f * float(x), 1.0f, 0.5f * float(y));
  sky.at(3, 2) = glm::vec3(1e6f);
  o.maps["sky.hdr"] = sky;
  prt::ImageRgb one(1, 1);
  one.at(0, 0) = glm::vec3(1.0f, 2.0f, 3.0f);
  o.maps["one.exr"] = one;
  prt::ImageRgb hot(4, 2);
  for (glm::vec3& p : hot.pixels) p = glm::vec3(9.99e29f);  // the largest a rig allows (float(1e30) is above)
  o.maps["hot.exr"] = hot;
  return o;
}

void checkFinite(const prt::LightRig& rig, double frame) {
  for (int bands : {1, 3, 8}) {
    const prt::sh::ShRgb sh = rig.evaluate(frame, bands);
    if (sh.size() != bands * bands) __builtin_trap();
    for (const glm::vec3& c : sh.c)
      if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.z)) __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const prt::RigReadOptions kOptions = options();
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  prt::LightRig rig;
  try {
    rig = prt::parseLightRigFromMemory(bytes, "fuzz.json", kOptions);
  } catch (const prt::Error&) {
    return 0;
  }
  // A rig that parsed is valid: evaluating it must not throw (a prt::Error would escape here,
  // which libFuzzer reports as a crash).
  const auto [first, last] = rig.keyRange();
  for (double frame : {first, last, 0.5 * (first + last), first + 0.25 * (last - first), first - 1.0, last + 0.5, 0.0})
    checkFinite(rig, frame);
  return 0;
}
