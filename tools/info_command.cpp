#include "info_command.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "file_kind.h"
#include "light_options.h"
#include "prt/bake/local_lights.h"
#include "prt/bake/memory_estimate.h"
#include "prt/bake/surface_bake.h"
#include "prt/bake_record.h"
#include "prt/error.h"
#include "prt/probe_grid.h"
#include "prt/progress.h"
#include "prt/scene.h"

namespace prt::tools {

namespace {

// The lights as they light the scene (docs/lights.md, "Lights inside the scene").
void printLights(const Scene& scene) {
  const std::vector<LocalLight> locals = bake::scenePunctualLightsAt(scene, 0.0);
  for (size_t k = 0, j = 0; k < scene.lights.size(); ++k) {
    const PunctualLight& p = scene.lights[k];
    const char* moved = p.node >= 0 && isAnimated(scene, p.node) ? ", moved by an animation" : "";
    if (p.type != PunctualLight::Type::Directional) {
      std::printf("  light %zu     %s%s\n", k, describeLocalLight(locals[j++]).c_str(), moved);
      continue;
    }
    const glm::vec3 e = p.color * p.intensity;
    std::printf(
        "  light %zu     directional '%s' (a sun) towards (%.4g, %.4g, %.4g), irradiance (%.4g, %.4g, %.4g)%s\n", k,
        p.name.c_str(), -p.direction.x, -p.direction.y, -p.direction.z, e.r, e.g, e.b, moved);
  }
  // Emissive surfaces light the scene too (their textures are not read here: factor × strength).
  for (const LocalLight& l : bake::emissiveLightsOf(scene))
    std::printf("  emissive    %s, %zu triangles, %.4g m²\n", l.label.substr(l.label.rfind(": ") + 2).c_str(),
                l.emitter->triangles.size(), l.emitter->area);
}

// A glTF scene: what it holds, what it costs in memory, and its bake record if it has one.
void infoGlb(const std::string& path) {
  Scene scene = loadScene(path);
  size_t vertices = 0, triangles = 0, receivers = 0, baked = 0, twoSided = 0, twoSidedVertices = 0;
  for (const MeshInstance& m : scene.meshes) {
    vertices += m.vertexCount();
    triangles += m.triangleCount();
    receivers += m.receiverOnly;
    baked += !m.transfer.empty();
    twoSided += m.hasBackTransfer();
    if (m.hasBackTransfer()) twoSidedVertices += m.vertexCount();
  }
  std::printf("%s: glTF scene\n", path.c_str());
  std::printf("  file        %s on disk\n", formatBytes(std::filesystem::file_size(path)).c_str());
  std::printf("  instances   %zu (%zu with transfer, %zu receivers)\n", scene.meshes.size(), baked, receivers);
  for (const std::string& line : describeReceivers(scene, "--receiver"))
    std::printf("  receiver    %s\n", line.c_str());
  std::printf("  vertices    %zu\n  triangles   %zu\n", vertices, triangles);
  std::printf("  materials   %zu, textures %zu, cameras %zu, lights %zu\n", scene.materials.size(),
              scene.textures.size(), scene.cameras.size(), scene.lights.size());
  for (size_t k = 0; k < scene.cameras.size(); ++k) {
    const Camera& c = scene.cameras[k];
    std::printf("  camera %zu    '%s', %s\n", k, c.name.c_str(),
                c.perspective ? cat("perspective, yfov ", c.yfov, " rad").c_str() : "orthographic");
  }
  printLights(scene);
  for (const Animation& an : scene.animations) {
    double end = 0.0;
    for (const AnimationChannel& ch : an.channels) end = std::max(end, ch.times.back());
    std::printf("  animation   '%s', %zu channels, %g s\n", an.name.c_str(), an.channels.size(), end);
  }
  std::printf("  bounds      (%g, %g, %g) .. (%g, %g, %g)\n", scene.boundsMin.x, scene.boundsMin.y, scene.boundsMin.z,
              scene.boundsMax.x, scene.boundsMax.y, scene.boundsMax.z);
  // The memory figures come from the bake's own estimate (the one --max-memory checks).
  const bake::BakeSettings defaults;
  const bake::MemoryEstimate loaded = bake::estimateBakeMemory(scene, defaults, nullptr, 1.0);
  std::printf(
      "  memory      %s when loaded (geometry, transfer, textures); baking it with the defaults "
      "(%d bands, %d samples, %d bounces) needs at most %s\n",
      formatBytes(loaded.scene).c_str(), defaults.bands, defaults.samples, defaults.bounces,
      formatBytes(loaded.total).c_str());
  if (baked > 0) {
    std::printf("  transfer    %d bands (%d RGB coefficients per vertex)\n", scene.transferBands,
                scene.transferBands * scene.transferBands);
    if (twoSided)
      std::printf("  two-sided   %zu instances, %zu vertices with back-side transfer (_PRT_SH_BACK_)\n", twoSided,
                  twoSidedVertices);
  } else {
    std::printf("  transfer    none (not baked)\n");
  }
  if (scene.bakeRecord) std::printf("  bake        %s\n", describeBakeRecord(*scene.bakeRecord).c_str());
  if (const BounceOperator* op = scene.bounceOperator.get()) {
    size_t own = 0;
    for (size_t v = 0; v < op->vertexRows.rows(); ++v) own += op->vertexRows.start[v + 1] > op->vertexRows.start[v];
    std::printf(
        "  operator    version %d: %u clusters of up to %d vertex sides, %zu cluster entries (%d a row asked for), %zu "
        "gradient entries (up to %d a row), %zu of %u vertex sides with rows of their own (%zu entries), %d x %d "
        "sky bins, %d rays per vertex side, %d bounces\n",
        op->version, op->clusters, op->clusterSize, op->clusterRows.entries(), op->clusterRowLength,
        op->clusterGradients.entries(), op->gradientRowLength, own, op->vertexSides, op->vertexRows.entries(),
        op->skyWidth, op->skyHeight, op->samples, op->bounces);
    const BounceOperator::ProbeRows& p = op->probeRows;
    if (p.present())
      std::printf("  probe rows  %zu probes of a %d x %d x %d grid, %zu entries (up to %d a row), %d rays per probe\n",
                  p.lattice.size(), p.dims.x, p.dims.y, p.dims.z, p.rows.entries(), p.rowLength, p.samples);
  } else if (baked > 0) {
    std::printf("  operator    none (prt render and prt relight trace the bake's rays again; bake with --operator)\n");
  }
  for (const std::string& w : scene.warnings) std::printf("  warning     %s\n", w.c_str());
}

}  // namespace

void addInfo(CLI::App& cmd, InfoArgs& a) {
  cmd.add_option("files", a.files, "Files to describe (.gltf, .glb, .vdb)")->required();
}

int runInfo(const InfoArgs& a) {
  int status = 0;
  for (const std::string& f : a.files) {
    try {
      std::string what;
      switch (sniffFile(f, what)) {
        case FileKind::ProbeGrid:
          std::printf("%s", describeProbeFile(f).c_str());
          break;
        case FileKind::Gltf:
          infoGlb(f);
          break;
        case FileKind::Other:
          throw Error(cat(f, ": not a glTF scene (.gltf, .glb) or a probe grid (.vdb): the file is ", what));
      }
    } catch (const Error& e) {
      std::fprintf(stderr, "prt: %s\n", e.what());
      status = 1;
    }
  }
  return status;
}

}  // namespace prt::tools
