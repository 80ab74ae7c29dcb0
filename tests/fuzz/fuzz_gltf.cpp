// libFuzzer target: glTF 2.0 (.gltf JSON or .glb) through the whole scene loader, from memory.
// Any outcome but a scene or a prt::Error (a crash, a sanitizer report, another exception,
// a leak, a huge allocation) is a bug. docs/robustness.md tells how to run it.
#include <cstddef>
#include <cstdint>
#include <string>

#include "prt/error.h"
#include "prt/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  try {
    // The name only matters for bytes without the GLB magic: they are read as JSON.
    prt::Scene scene = prt::loadSceneFromMemory("fuzz.gltf", bytes);
    // Touch what the loader promises: finite world positions, indices within the vertices.
    for (const prt::MeshInstance& m : scene.meshes)
      for (uint32_t i : m.indices)
        if (i >= m.vertexCount()) __builtin_trap();
  } catch (const prt::Error&) {}
  return 0;
}
