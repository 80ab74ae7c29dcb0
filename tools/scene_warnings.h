// The warnings a loaded scene carries (skipped or repaired input), printed by the commands.
#pragma once

#include <cstdio>
#include <string>

#include "prt/scene.h"

namespace prt::tools {

/// One "prt: warning: ..." line per warning on stderr, none when `quiet`.
inline void printWarnings(const Scene& scene, bool quiet) {
  if (quiet) return;
  for (const std::string& w : scene.warnings) std::fprintf(stderr, "prt: warning: %s\n", w.c_str());
}

}  // namespace prt::tools
