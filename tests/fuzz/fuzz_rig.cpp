// libFuzzer target: light rigs (JSON, docs/lights.md) through parseLightRigFromMemory, then
// what a rig promises once it parses: evaluate() at frames in and around its keys, on 1, 3 and
// 8 bands, gives finite SH and throws nothing. A NaN or an infinity aborts, and a prt::Error
// from evaluate() escapes (libFuzzer reports both as crashes and keeps the input).
// Environment lights use maps in memory (fuzz_rig.h). docs/robustness.md tells how to run it.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_rig.h"
#include "prt/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const prt::RigReadOptions kOptions = prt::fuzz::rigOptions();
  if (!prt::fuzz::rigProblem(std::string(reinterpret_cast<const char*>(data), size), kOptions).empty())
    __builtin_trap();
  return 0;
}
