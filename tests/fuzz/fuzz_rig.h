// What fuzz_rig runs on each input, shared with the test suite, which replays the seeds and
// regressions of tests/fuzz/{corpus,regressions}/rig through the same code (FuzzRegressions.Rig).
#pragma once

#include <cmath>
#include <string>

#include "prt/error.h"
#include "prt/light_rig.h"

namespace prt::fuzz {

/// The maps a fuzzed rig may name, all in memory (no file is ever read): "sky.hdr" (smooth, with
/// a bright spot), "one.exr" (a single pixel) and "hot.exr" (every pixel near the largest
/// radiance a rig allows: just under 1e30, since float(1e30) is above it).
inline RigReadOptions rigOptions() {
  RigReadOptions o;  // baseDir "": no files
  ImageRgb sky(16, 8);
  for (int y = 0; y < sky.height; ++y)
    for (int x = 0; x < sky.width; ++x) sky.at(x, y) = glm::vec3(0.2f + 0.1f * float(x), 1.0f, 0.5f * float(y));
  sky.at(3, 2) = glm::vec3(1e6f);
  o.maps["sky.hdr"] = sky;
  ImageRgb one(1, 1);
  one.at(0, 0) = glm::vec3(1.0f, 2.0f, 3.0f);
  o.maps["one.exr"] = one;
  ImageRgb hot(4, 2);
  for (glm::vec3& p : hot.pixels) p = glm::vec3(9.99e29f);
  o.maps["hot.exr"] = hot;
  return o;
}

/// Parses `bytes` as fuzz_rig does; a rig that parses is evaluated at frames in and around its
/// keys on 1, 3 and 8 bands. Returns "" when all is well (a rig with finite SH, or a prt::Error
/// from the parser in one short line), else what went wrong. A prt::Error from evaluate() (a
/// valid rig must evaluate) propagates.
inline std::string rigProblem(const std::string& bytes, const RigReadOptions& options) {
  // The longest message the reader writes: fixed text, element paths and 40-byte quotes.
  constexpr size_t kMaxMessage = 300;
  LightRig rig;
  try {
    rig = parseLightRigFromMemory(bytes, "fuzz.json", options);
  } catch (const Error& e) {
    const std::string what = e.what();
    if (what.find('\n') != std::string::npos) return "message on several lines: " + what;
    if (what.size() > kMaxMessage) return "message of " + std::to_string(what.size()) + " bytes: " + what;
    return "";
  }
  const auto [first, last] = rig.keyRange();
  for (double frame : {first, last, 0.5 * (first + last), first + 0.25 * (last - first), first - 1.0, last + 0.5, 0.0})
    for (int bands : {1, 3, 8}) {
      const sh::ShRgb sh = rig.evaluate(frame, bands);
      if (sh.size() != bands * bands) return "wrong coefficient count";
      for (const glm::vec3& c : sh.c)
        if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.z))
          return "coefficient not finite at frame " + std::to_string(frame) + ", " + std::to_string(bands) + " bands";
    }
  return "";
}

}  // namespace prt::fuzz
