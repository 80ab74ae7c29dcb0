// What light_rig.cpp (the model, validation, evaluation) and light_rig_json.cpp (the reader)
// share. Private to prt::lights.
#pragma once

#include "prt/error.h"
#include "prt/light_rig.h"

namespace prt::detail {

/// Refuses a frame rate outside RigLimits through `check.fail("fps", problem)`: the reader
/// checks it as it reads, validate() again for a rig made in code.
template <class Check>
void checkFps(const Check& check, double fps) {
  if (!(fps >= RigLimits::kMinFps && fps <= RigLimits::kMaxFps))
    check.fail("fps", cat("must be in [", RigLimits::kMinFps, ", ", RigLimits::kMaxFps, "] frames per second (got ",
                          fps, ")"));
}

}  // namespace prt::detail
