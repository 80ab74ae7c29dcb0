#include "relight_command.h"

#include <algorithm>
#include <cstdio>
#include <fstream>

#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/relight.h"
#include "prt/scene.h"
#include "scene_warnings.h"

namespace prt::tools {

namespace {

// One row per vertex; a double-sided vertex has a second row for its back side, with the
// normal negated, after its instance's front rows.
void writeCsv(const std::string& path, const Scene& scene, const std::vector<std::vector<glm::vec3>>& radiance,
              const std::vector<std::vector<glm::vec3>>& back) {
  AtomicFile file(path);
  {
    std::ofstream out(file.tempPath());
    if (!out) throw Error(cat(path, ": cannot write"));
    out << "node,primitive,vertex,px,py,pz,nx,ny,nz,r,g,b\n";
    out.precision(9);
    for (size_t k = 0; k < scene.meshes.size(); ++k) {
      const MeshInstance& m = scene.meshes[k];
      for (size_t v = 0; v < radiance[k].size(); ++v) {
        const glm::vec3 &p = m.positions[v], &n = m.normals[v], &c = radiance[k][v];
        out << m.node << ',' << m.primitive << ',' << v << ',' << p.x << ',' << p.y << ',' << p.z << ','
            << n.x << ',' << n.y << ',' << n.z << ',' << c.r << ',' << c.g << ',' << c.b << '\n';
      }
      for (size_t v = 0; v < back[k].size(); ++v) {
        const glm::vec3 &p = m.positions[v], n = -m.normals[v], &c = back[k][v];
        out << m.node << ',' << m.primitive << ',' << v << ',' << p.x << ',' << p.y << ',' << p.z << ','
            << n.x << ',' << n.y << ',' << n.z << ',' << c.r << ',' << c.g << ',' << c.b << '\n';
      }
    }
    if (!out.flush()) throw Error(cat(path, ": cannot write"));
  }
  file.commit();
}

}  // namespace

void addRelight(CLI::App& cmd, RelightArgs& a) {
  cmd.add_option("baked", a.baked, "Baked scene (.glb from prt bake)")->required();
  cmd.add_option("-o,--output", a.output, "Output lit scene (.glb, unlit vertex colours)")->required();
  cmd.add_option("--csv", a.csv, "Also write per-vertex radiance as CSV");
  addLightOptions(cmd, a.light);
  cmd.add_flag("-q,--quiet", a.quiet, "No summary");
}

int runRelight(const RelightArgs& a) {
  AtomicFile probe(a.output);
  Scene scene = loadScene(a.baked);
  printWarnings(scene, a.quiet);
  // A bake whose every instance is a receiver has bands (its record's) but nothing to relight.
  const bool anyTransfer =
      std::any_of(scene.meshes.begin(), scene.meshes.end(), [](const MeshInstance& m) { return !m.transfer.empty(); });
  if (!anyTransfer) throw Error(cat(a.baked, ": holds no baked transfer (run prt bake first)"));
  sh::ShRgb light = buildLight(a.light, scene.transferBands);
  std::vector<std::vector<glm::vec3>> radiance = relightVertices(scene, light);
  std::vector<std::vector<glm::vec3>> back = relightBackVertices(scene, light);
  if (!a.csv.empty()) AtomicFile csvProbe(a.csv);
  writeLitScene(a.baked, scene, radiance, a.output, &back);
  if (!a.csv.empty()) writeCsv(a.csv, scene, radiance, back);
  if (a.quiet) return 0;
  size_t vertices = 0;
  glm::vec3 sum(0.0f);
  size_t backSides = 0;
  for (const auto& r : radiance)
    for (const glm::vec3& c : r) {
      sum += c;
      ++vertices;
    }
  for (const auto& r : back) backSides += r.size();
  glm::vec3 mean = vertices ? sum / float(vertices) : glm::vec3(0);
  std::string lighting = a.light.rig.empty() ? std::string() : cat(", lit by ", a.light.rig, " at frame ", a.light.frame);
  const std::string sides = backSides ? cat(" (", backSides, " of them two-sided)") : std::string();
  std::fprintf(stderr, "prt relight: %s -> %s%s%s\n  %zu vertices%s, %d bands%s, mean exitant radiance (%.4g, %.4g, %.4g)\n",
               a.baked.c_str(), a.output.c_str(), a.csv.empty() ? "" : " + ", a.csv.c_str(), vertices, sides.c_str(),
               scene.transferBands, lighting.c_str(), mean.r, mean.g, mean.b);
  return 0;
}

}  // namespace prt::tools
