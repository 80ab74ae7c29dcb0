// Render benchmark: ms per frame of the full relighting path (baked instances + receivers lit
// from the probe grid) next to the raster floor, a flat-shaded draw of the same instances with
// the same vertex buffers, depth test and read-back, measured in the same run; and the cost of a
// light update for 1M baked vertices and for a 32³ probe grid.
//
//   prt_bench_render [--width 1920] [--height 1080] [--frames 12] [--gl osmesa|egl]
//                    [--baked FILE.glb --probes FILE.vdb] [--samples 128] [--probe-dims 16]
//                    [--frames-only 0|1] [--sun-only 0|1] [--materials-only 0|1] [--lamp-only 0|1]
//                    [--lamp X,Y,Z] [--lamp-radius 0.5] [--json out.json]
//
// Without --baked/--probes the bundled Cornell room (scenes/cornell_open.gltf) is baked in the
// process (surface transfer with --samples directions and 1 bounce, a --probe-dims³ probe
// grid), which takes a few seconds and is not timed. Frames sweep the receiver's animation
// (frame i at time i / frames · duration) under a rotating sky, so every frame relights.
// Four kinds of frame are interleaved (full with the per-pixel probe lookup, full with the
// per-vertex lookup, flat, baked instances only; the order rotates from frame to frame) and
// compared frame by frame, wall and process CPU time
// (CLOCK_PROCESS_CPUTIME_ID: llvmpipe's and TBB's threads included), so that the load of a
// shared machine falls on all kinds alike. --frames-only 1 skips the light-update part, which
// ends with `prt render`'s own light update (frame_lighting: the rig, shadow rays and the gather
// over the bake's rays, bake::FrameLighting), and the same through the bounce operator
// (frame_lighting_operator; operator_build: its build time next to the surface bake's, its
// size) beside the SH product alone (relight_cpu_ms, for 1M vertices).
// The `sun` part (sunShadows) times the same frame with a sun lit per pixel with its shadow maps
// against the frame with the sun through SH (docs/render.md, "Direct lights and their shadows");
// --sun-only 1 stops after it and the material frames (full glTF material against the diffuse
// frame, "materials" in the JSON); --materials-only 1 times the material frames alone.
// The `lamp` part (lampLighting) times a moving point lamp's light update next to the SH product
// alone; --lamp-only 1 times it alone (a large --baked scene: give --lamp inside it).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>

#include <sys/resource.h>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_cli.h"
#include "cpu_clock.h"
#include "prt/bake/bounce_operator.h"
#include "prt/bake/frame_lighting.h"
#include "prt/bake/probe_bake.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"
#include "prt/huge_pages.h"
#include "prt/image.h"
#include "prt/light.h"
#include "prt/light_rig.h"
#include "prt/local_light.h"
#include "prt/math.h"
#include "prt/probe_grid.h"
#include "prt/relight.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "prt/scene.h"
#include "prt/sh.h"

namespace {

using namespace prt;
using Clock = std::chrono::steady_clock;

using bench::median;
using bench::msSince;

// CPU time of the whole process (all threads), ms.
double processCpuMs() { return 1e3 * bench::processCpuSeconds(); }

// Splits every triangle into 4 (midpoints shared through an edge map), interpolating normals and
// transfer (its direct part too): the refined mesh a denser bake would give.
void refine(MeshInstance& m, int bands) {
  const size_t n2 = size_t(bands) * size_t(bands);
  std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
  auto midpoint = [&](uint32_t a, uint32_t b) {
    const auto key = std::minmax(a, b);
    const auto it = mid.find(key);
    if (it != mid.end()) return it->second;
    const uint32_t i = uint32_t(m.positions.size());
    m.positions.push_back(0.5f * (m.positions[a] + m.positions[b]));
    m.normals.push_back(glm::normalize(m.normals[a] + m.normals[b]));
    for (size_t k = 0; k < n2; ++k) m.transfer.push_back(0.5f * (m.transfer[a * n2 + k] + m.transfer[b * n2 + k]));
    if (m.hasDirectTransfer())
      for (size_t k = 0; k < n2; ++k)
        m.transferDirect.push_back(0.5f * (m.transferDirect[a * n2 + k] + m.transferDirect[b * n2 + k]));
    mid.emplace(key, i);
    return i;
  };
  std::vector<uint32_t> out;
  out.reserve(m.indices.size() * 4);
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    const uint32_t a = m.indices[3 * t], b = m.indices[3 * t + 1], c = m.indices[3 * t + 2];
    const uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
    out.insert(out.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
  }
  m.indices = std::move(out);
}

size_t bakedVertices(const Scene& s) {
  size_t n = 0;
  for (const MeshInstance& m : s.meshes)
    if (!m.receiverOnly) n += m.vertexCount();
  return n;
}

// A sky with structure in every band of 3, turned about +Y by `degrees`.
sh::ShRgb sky(double degrees) {
  sh::ShRgb l(3);
  l.c[0] = glm::vec3(3.0f, 2.8f, 2.5f);
  l.c[1] = glm::vec3(1.5f);
  l.c[3] = glm::vec3(0.8f, 0.5f, 0.2f);
  l.c[6] = glm::vec3(0.4f);
  l.c[8] = glm::vec3(0.2f, 0.1f, 0.0f);
  return sh::Rotation(3, sh::rotationY(degrees)).apply(l);
}

struct Timing {
  std::vector<double> light, draw, readback, total, cpu;  // per frame, ms
  std::vector<double> faults;                             // minor page faults per frame
  double frameMs() const { return median(light) + median(draw) + median(readback); }
  nlohmann::json json() const {
    return {{"light_ms", median(light)}, {"draw_ms", median(draw)}, {"readback_ms", median(readback)},
            {"frame_ms", frameMs()},     {"cpu_ms", median(cpu)},   {"page_faults", median(faults)}};
  }
};

void record(Timing& t, const render::FrameStats& s, double cpuMs = 0.0) {
  t.light.push_back(s.lightMs);
  t.draw.push_back(s.drawMs);
  t.readback.push_back(s.readbackMs);
  t.total.push_back(s.lightMs + s.drawMs + s.readbackMs);
  t.cpu.push_back(cpuMs);
}

// Median over frames of a[i] / b[i]: frames of the two kinds ran next to each other.
double medianRatio(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> r;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) r.push_back(a[i] / b[i]);
  return median(r);
}

long minorFaults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt;
}

// Renders `f` and records wall and CPU time and page faults; the image is dropped.
void timedRender(render::Renderer& r, const render::Frame& f, Timing* t) {
  const long faults0 = minorFaults();
  const double cpu0 = processCpuMs();
  r.render(f);
  const double cpu = processCpuMs() - cpu0;
  if (t) {
    record(*t, r.lastFrame(), cpu);
    t->faults.push_back(double(minorFaults() - faults0));
  }
}

size_t differingPixels(const ImageRgb& a, const ImageRgb& b) {
  size_t n = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) n += a.at(x, y) != b.at(x, y);
  return n;
}

// A 32³ (or n³) grid of random transfer, all probes valid: the light update does not depend
// on the values.
ProbeGrid randomGrid(int n, int bands) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-0.1f, 1.0f);
  ProbeGrid g;
  g.bands = bands;
  g.dims = glm::ivec3(n);
  g.origin = glm::dvec3(-1.0, 0.0, -1.0);
  g.spacing = glm::dvec3(2.0 / (n - 1));
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) g.coord.emplace_back(x, y, z);
  g.transfer.resize(g.probeCount() * g.transferStride());
  for (float& v : g.transfer) v = u(rng);
  g.validity.assign(g.probeCount(), 1.0f);
  g.offset.assign(g.probeCount(), glm::vec3(0.0f));
  g.skyVisibility.assign(g.probeCount(), 1.0f);
  std::array<glm::vec2, 6> m;
  m.fill(glm::vec2(1.0f, 1.0f));
  g.moments.assign(g.probeCount(), m);
  g.buildIndex();
  return g;
}

// A frame with sun shadows against the same frame without them, interleaved, same run: the sky
// and the receiver as in the main frames, plus a sun (0.265°, elevation 40°, its azimuth turning
// 10° a frame so that every frame draws new shadow maps) lit as `prt render` lights it:
// - sun_shadows: the sun per pixel with its PCSS-filtered shadow maps (Frame::direct);
// - sun_unshadowed: per pixel, every visible share 1 (no shadow map drawn);
// - sun_through_sh: --no-direct-lights, the sun's SH through the whole transfer, no direct
//   term: the frame before direct lights existed, the one "without sun shadows";
// - flat: the raster floor.
nlohmann::json sunShadows(render::Renderer& renderer, const Scene& scene, const render::CameraView& view, int frames) {
  const int bands = renderer.bands();
  const double duration = animationDuration(scene);
  Timing shadowed, unshadowed, throughSh, flat;
  std::vector<double> shadowMs;
  render::FrameStats last;
  for (int i = -2; i < frames; ++i) {
    DirectLight sun;
    sun.direction = azimuthElevationDirection(30.0 + 10.0 * std::max(i, 0), 40.0);
    sun.radius = glm::radians(0.265);
    sun.irradiance = glm::dvec3(6.0, 5.6, 5.0);
    render::Frame f;
    f.camera = view;
    f.time = i < 0 ? 0.0 : duration * i / frames;
    f.light = sky(360.0 * std::max(i, 0) / frames);
    f.directLight = sun.project(bands);
    f.direct = {sun};
    render::Frame noShadow = f, viaSh = f, flatFrame = f;
    noShadow.shadows.enabled = false;
    viaSh.light += viaSh.directLight;
    viaSh.directLight = sh::ShRgb();
    viaSh.direct.clear();
    flatFrame.shading = render::Shading::Flat;
    for (int k = 0; k < 4; ++k) {
      switch ((k + std::max(i, 0)) % 4) {
        case 0:
          timedRender(renderer, f, i >= 0 ? &shadowed : nullptr);
          if (i >= 0) shadowMs.push_back(renderer.lastFrame().shadowMs);
          last = renderer.lastFrame();
          break;
        case 1:
          timedRender(renderer, noShadow, i >= 0 ? &unshadowed : nullptr);
          break;
        case 2:
          timedRender(renderer, viaSh, i >= 0 ? &throughSh : nullptr);
          break;
        default:
          timedRender(renderer, flatFrame, i >= 0 ? &flat : nullptr);
          break;
      }
    }
  }
  return {{"sun_radius_deg", 0.265},
          {"shadow_map_size", last.shadowMapSize},
          {"cascades", last.cascades},
          {"direct_lights_baked", last.directBaked},
          {"direct_lights_receivers", last.directReceivers},
          {"shadow_pass_ms", median(shadowMs)},
          {"sun_shadows", shadowed.json()},
          {"sun_unshadowed", unshadowed.json()},
          {"sun_through_sh", throughSh.json()},
          {"flat", flat.json()},
          {"ratio_shadows_to_without", medianRatio(shadowed.total, throughSh.total)},
          {"cpu_ratio_shadows_to_without", medianRatio(shadowed.cpu, throughSh.cpu)},
          {"ratio_shadows_to_unshadowed", medianRatio(shadowed.total, unshadowed.total)},
          {"cpu_ratio_shadows_to_unshadowed", medianRatio(shadowed.cpu, unshadowed.cpu)},
          {"ratio_shadows_to_flat", medianRatio(shadowed.total, flat.total)},
          {"ratio_without_to_flat", medianRatio(throughSh.total, flat.total)},
          {"target_ratio", 1.5}};
}

// The glTF material in full against today's diffuse frame, same renderer, interleaved (issue's
// target: full ≤ 1.5 × diffuse): the room with a glossy floor (roughness 0.35) and a copper short
// box (metallic 1, roughness 0.4), the sky and a sun as in the sun frames (shadow maps), the
// bundled map reflected (prefiltered once, before the timed frames). `full`:
// MaterialShading::Full; `diffuse`: the same frame Lambertian; `flat`: the raster floor;
// `glossy`: the full frame with every other material at roughness 0.5 too (the walls and the tall
// box reflect the map: the cost where no pixel is rough enough to skip the environment's lookups);
// `reflections` and `glossy_reflections`: those two with Frame::screenReflections (prt render's
// default), which `full` and `glossy` leave out.
nlohmann::json materialFrames(render::GlContext& context, Scene scene, const ProbeGrid& grid,
                              const render::CameraView& view, int frames) {
  Material glossy = scene.materials.at(0), copper = scene.materials.at(0);
  glossy.name = "glossy_floor";
  glossy.roughnessFactor = 0.35f;
  copper.name = "copper";
  copper.baseColorFactor = glm::vec4(0.95f, 0.64f, 0.54f, 1.0f);
  copper.metallicFactor = 1.0f;
  copper.roughnessFactor = 0.4f;
  scene.materials.push_back(glossy);
  scene.materials.push_back(copper);
  for (MeshInstance& m : scene.meshes) {
    if (m.name.rfind("Floor", 0) == 0) m.material = int(scene.materials.size()) - 2;
    if (m.name.rfind("ShortBox", 0) == 0) m.material = int(scene.materials.size()) - 1;
  }
  render::Renderer renderer(context, scene);
  renderer.setProbes(grid);
  Scene glossyScene = scene;
  for (size_t i = 0; i + 2 < glossyScene.materials.size(); ++i) glossyScene.materials[i].roughnessFactor = 0.5f;
  render::Renderer glossyRenderer(context, glossyScene);
  glossyRenderer.setProbes(grid);
  RigBackground environment;
  environment.maps.push_back(
      {std::make_shared<const ImageRgb>(loadHdrImage(PRT_SOURCE_DIR "/scenes/env/royal_esplanade_128.hdr")),
       glm::dmat3(1.0), glm::dvec3(1.0)});
  const double duration = animationDuration(scene);
  Timing full, diffuse, flat, glossyFull, reflections, glossyReflections;
  for (int i = -2; i < frames; ++i) {
    DirectLight sun;
    sun.direction = azimuthElevationDirection(30.0 + 10.0 * std::max(i, 0), 40.0);
    sun.radius = glm::radians(0.265);
    sun.irradiance = glm::dvec3(6.0, 5.6, 5.0);
    render::Frame f;
    f.camera = view;
    f.time = i < 0 ? 0.0 : duration * i / frames;
    f.light = sky(360.0 * std::max(i, 0) / frames);
    f.directLight = sun.project(renderer.bands());
    f.direct = {sun};
    f.materials = render::MaterialShading::Full;
    f.environment = &environment;
    f.screenReflections = false;
    render::Frame d = f, flatFrame = f, ssr = f;
    d.materials = render::MaterialShading::Diffuse;
    flatFrame.shading = render::Shading::Flat;
    ssr.screenReflections = true;
    for (int k = 0; k < 6; ++k) {
      const int kind = (k + std::max(i, 0)) % 6;
      Timing* timing[6] = {&full, &diffuse, &flat, &glossyFull, &reflections, &glossyReflections};
      const render::Frame* frame[6] = {&f, &d, &flatFrame, &f, &ssr, &ssr};
      timedRender(kind == 3 || kind == 5 ? glossyRenderer : renderer, *frame[kind], i < 0 ? nullptr : timing[kind]);
    }
  }
  return {{"full", full.json()},
          {"diffuse", diffuse.json()},
          {"flat", flat.json()},
          {"ratio_full_to_diffuse", medianRatio(full.total, diffuse.total)},
          {"cpu_ratio_full_to_diffuse", medianRatio(full.cpu, diffuse.cpu)},
          {"glossy", glossyFull.json()},
          {"ratio_glossy_to_diffuse", medianRatio(glossyFull.total, diffuse.total)},
          {"cpu_ratio_glossy_to_diffuse", medianRatio(glossyFull.cpu, diffuse.cpu)},
          {"reflections", reflections.json()},
          {"ratio_reflections_to_diffuse", medianRatio(reflections.total, diffuse.total)},
          {"cpu_ratio_reflections_to_diffuse", medianRatio(reflections.cpu, diffuse.cpu)},
          {"glossy_reflections", glossyReflections.json()},
          {"ratio_glossy_reflections_to_diffuse", medianRatio(glossyReflections.total, diffuse.total)},
          {"cpu_ratio_glossy_reflections_to_diffuse", medianRatio(glossyReflections.cpu, diffuse.cpu)},
          {"target_ratio", 1.5}};
}

// The receivers' cost per pixel, apart from the frame: an orbit camera close to the receivers
// (their bounds at rest) so that they fill much of the frame; CPU time of full frames with the
// per-pixel and the per-vertex lookup, frames of the baked instances alone and flat frames, the
// kinds interleaved. A receiver pixel costs (full − baked alone) / receiver pixels; a flat
// frame's pixel costs flat / (width · height). Their quotient, times the share of the frame a
// receiver covers, is what the receiver adds to a frame's ratio to the raster floor.
nlohmann::json receiverCloseup(render::Renderer& renderer, render::Renderer& bakedOnly, const Scene& scene, int width,
                               int height, int frames) {
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
  for (const MeshInstance& m : scene.meshes)
    if (m.receiverOnly)
      for (const glm::vec3& p : m.positions) {
        lo = glm::min(lo, glm::dvec3(p));
        hi = glm::max(hi, glm::dvec3(p));
      }
  if (lo.x > hi.x) return nullptr;
  render::OrbitCamera orbit;
  orbit.target = glm::vec3(0.5 * (lo + hi));
  orbit.distance = 0.8 * glm::length(hi - lo);
  orbit.azimuthDegrees = 30.0;
  orbit.elevationDegrees = 10.0;
  render::Frame f;
  f.camera = render::orbitView(scene, orbit, double(width) / height);
  f.light = sky(30.0);
  render::Frame flatFrame = f, vertexFrame = f;
  flatFrame.shading = render::Shading::Flat;
  vertexFrame.probeLookup = render::ProbeLookup::PerVertex;
  Timing full, vertex, baked, flat;
  for (int i = -2; i < frames; ++i)
    for (int k = 0; k < 4; ++k) switch ((k + std::max(i, 0)) % 4) {
        case 0:
          timedRender(renderer, f, i >= 0 ? &full : nullptr);
          break;
        case 1:
          timedRender(renderer, vertexFrame, i >= 0 ? &vertex : nullptr);
          break;
        case 2:
          timedRender(bakedOnly, f, i >= 0 ? &baked : nullptr);
          break;
        default:
          timedRender(renderer, flatFrame, i >= 0 ? &flat : nullptr);
          break;
      }
  const size_t pixels = differingPixels(renderer.render(f), bakedOnly.render(f));
  const double flatNs = median(flat.cpu) * 1e6 / (double(width) * height);
  const double pixelNs = (median(full.cpu) - median(baked.cpu)) * 1e6 / double(std::max<size_t>(pixels, 1));
  const double vertexNs = (median(vertex.cpu) - median(baked.cpu)) * 1e6 / double(std::max<size_t>(pixels, 1));
  return {{"receiver_pixels", pixels},
          {"prt_cpu_ms", median(full.cpu)},
          {"per_vertex_cpu_ms", median(vertex.cpu)},
          {"baked_only_cpu_ms", median(baked.cpu)},
          {"flat_cpu_ms", median(flat.cpu)},
          {"flat_ns_per_frame_pixel", flatNs},
          {"receiver_ns_per_pixel", pixelNs},
          {"receiver_ns_per_pixel_per_vertex_lookup", vertexNs},
          {"receiver_pixel_in_flat_pixels", pixelNs / flatNs},
          {"receiver_pixel_in_flat_pixels_per_vertex_lookup", vertexNs / flatNs}};
}

// The light updates: 1M baked vertices (a uniform; the dot product runs per vertex), and a 32³
// probe grid (relightProbes + pack + upload).
nlohmann::json lightUpdates(render::GlContext& context, const Scene& scene, const render::CameraView& view) {
  // --- Light update, 1M baked vertices (the static path) ----------------------------------
  Scene dense = scene;
  dense.meshes.erase(
      std::remove_if(dense.meshes.begin(), dense.meshes.end(), [](const MeshInstance& m) { return m.receiverOnly; }),
      dense.meshes.end());
  for (size_t k = 0; bakedVertices(dense) < 1000000; k = (k + 1) % dense.meshes.size())
    refine(dense.meshes[k], dense.transferBands);
  size_t denseTriangles = 0;
  for (const MeshInstance& m : dense.meshes) denseTriangles += m.triangleCount();
  std::vector<double> cpuRelight;
  for (int i = 0; i < 5; ++i) {
    const auto t0 = Clock::now();
    const auto radiance = relightVertices(dense, sky(10.0 * i));
    cpuRelight.push_back(msSince(t0));
  }
  Timing densePrt, denseFlat;
  {
    render::Renderer r(context, dense);
    for (int i = -1; i < 5; ++i) {
      render::Frame f;
      f.camera = view;
      f.light = sky(10.0 * i);
      r.render(f);
      if (i >= 0) record(densePrt, r.lastFrame());
      f.shading = render::Shading::Flat;
      r.render(f);
      if (i >= 0) record(denseFlat, r.lastFrame());
    }
  }

  // --- Light update, 32³ probes: relightProbes + upload -----------------------------------
  const ProbeGrid big = randomGrid(32, 3);
  std::vector<double> relightOnly, relightCpu, probeUpdate;
  for (int i = 0; i < 10; ++i) {
    const auto t0 = Clock::now();
    const double cpu0 = processCpuMs();
    const std::vector<glm::vec3> relit = relightProbes(big, sky(7.0 * i));
    relightOnly.push_back(msSince(t0));
    relightCpu.push_back(processCpuMs() - cpu0);
  }
  {
    render::Renderer r(context, scene);
    r.setProbes(big);
    for (int i = -1; i < 10; ++i) {
      render::Frame f;
      f.camera = view;
      f.light = sky(7.0 * i);
      f.width = 64;
      f.height = 36;
      r.render(f);
      if (i >= 0) probeUpdate.push_back(r.lastFrame().lightMs);
    }
  }

  nlohmann::json j;
  j["light_update_1M_vertices"] = {
      {"vertices", bakedVertices(dense)},        {"triangles", denseTriangles},
      {"gl_light_ms", median(densePrt.light)},   {"gl_prt_frame_ms", densePrt.frameMs()},
      {"gl_flat_frame_ms", denseFlat.frameMs()}, {"cpu_relight_vertices_ms", median(cpuRelight)}};
  j["light_update_32cubed_probes"] = {{"probes", big.probeCount()},
                                      {"bands", big.bands},
                                      {"relight_ms", median(relightOnly)},
                                      {"relight_cpu_ms", median(relightCpu)},
                                      {"relight_and_upload_ms", median(probeUpdate)},
                                      {"target_ms", 10.0}};
  return j;
}

// The light update of `prt render` (bake::FrameLighting): the bundled environment map turning
// 360° over the frames and a sun, so that every frame evaluates the rig and gathers its direct
// lights' bounces and the sky detail over the bake's rays again (traced once, at the first
// frame: trace_s), or, `useOperator`, through the scene's bounce operator (nothing traced), then
// draws. light_update_ms is the frame's light without the renderer's part.
nlohmann::json frameLighting(render::Renderer& renderer, const Scene& scene, const render::CameraView& view, int frames,
                             bool useOperator) {
  LightRig rig;
  RigLight env;
  env.type = RigLight::Type::Environment;
  env.file = PRT_SOURCE_DIR "/scenes/env/royal_esplanade_128.hdr";
  env.rotation = Track::ramp(0.0, 0.0, frames, 360.0);
  RigLight sun;
  sun.type = RigLight::Type::Sun;
  sun.colorIsIrradiance = true;
  sun.direction = Track::constant(glm::normalize(glm::dvec3(0.3, 0.8, 0.5)));
  sun.color = Track::constant(glm::dvec3(6.0, 5.6, 5.0));
  rig.lights = {env, sun};
  rig.validate();
  rig.prepare(renderer.bands());
  bake::FrameLightingSettings settings;
  settings.shadowSamples = 4;  // prt render's shadow rays for the light that bounces
  settings.useOperator = useOperator;
  bake::FrameLighting lighting(scene, rig, settings);
  Timing timing;
  std::vector<double> updateMs;
  for (int i = -1; i < frames; ++i) {
    bake::FrameLight light = lighting.at(std::max(i, 0));
    render::Frame f;
    f.camera = view;
    const bake::DirectIrradiance* v = light.vertexLight;
    f.setLight(std::move(light.rig), v ? &v->front : nullptr, v ? &v->back : nullptr);
    timedRender(renderer, f, i >= 0 ? &timing : nullptr);
    if (i >= 0) updateMs.push_back(1e3 * light.seconds);
  }
  const bake::FrameLightingStats& st = lighting.stats();
  return {{"through_operator", lighting.usesOperator()},
          {"gather_samples", settings.gatherSamples},
          {"gather_rays", st.gatherRays},
          {"shadow_ms", 1e3 * st.shadowSeconds / std::max(st.updates, 1)},
          {"gather_ms", 1e3 * st.gatherSeconds / std::max(st.updates, 1)},
          {"trace_s", st.traceSeconds},
          {"updates", st.updates},
          {"light_update_ms", median(updateMs)},
          {"frame", timing.json()}};
}

// A moving lamp's light update (docs/render.md, "Cost of a moving lamp"): a point light circling
// `centre` at `radius` about +Y, a new place every frame, lit as `prt render` lights it: per
// pixel with its cube shadow maps, and at the baked vertices its E⁰ (one shadow ray per vertex
// side) sent on through the bake's bounce operator where it has one, else gathered over the
// bake's rays (traced once, at the first frame: trace_s). Next to it, interleaved in the same
// run, the SH product alone: relightVertices of a turning sky on the same vertices, what a light
// change costs the distant lights. light_update_ms is FrameLighting's whole update (the rig,
// the shadow rays, the products); the frame's draw includes the cube maps' pass (cube_shadow_ms).
nlohmann::json lampLighting(render::Renderer& renderer, const Scene& scene, const render::CameraView& view, int frames,
                            const glm::dvec3& centre, double radius) {
  LightRig rig;
  RigLocalLight lamp;
  lamp.type = LocalLight::Type::Point;
  lamp.label = "bench lamp";
  lamp.color = Track::constant(glm::dvec3(2.0, 1.7, 1.3));
  lamp.position.keys.clear();
  for (int i = 0; i <= frames; ++i) {
    const double a = 2.0 * kPi * i / frames;
    lamp.position.keys.push_back({double(i), centre + radius * glm::dvec3(std::sin(a), 0.0, std::cos(a))});
  }
  rig.locals.push_back(lamp);
  rig.fps = 24.0;
  rig.validate();
  rig.prepare(renderer.bands());
  bake::FrameLightingSettings settings;
  settings.shadowSamples = 4;        // prt render's (kBounceShadowSamples)
  settings.localShadowSamples = 64;  // prt render's (kLocalShadowSamples)
  settings.localPerPixel = true;
  bake::FrameLighting lighting(scene, rig, settings);
  Timing timing;
  std::vector<double> updateMs, productMs, cubeMs;
  for (int i = -1; i < frames; ++i) {
    const auto t0 = Clock::now();
    const auto radiance = relightVertices(scene, sky(30.0 * std::max(i, 0)));
    if (i >= 0) productMs.push_back(msSince(t0));
    bake::FrameLight light = lighting.at(std::max(i, 0) + 0.5);
    render::Frame f;
    f.camera = view;
    const bake::DirectIrradiance* v = light.vertexLight;
    for (const LocalLight& l : light.local) f.local.push_back(l);
    f.setLight(std::move(light.rig), v ? &v->front : nullptr, v ? &v->back : nullptr);
    timedRender(renderer, f, i >= 0 ? &timing : nullptr);
    if (i >= 0) {
      updateMs.push_back(1e3 * light.seconds);
      cubeMs.push_back(renderer.lastFrame().shadowMs);
    }
  }
  const bake::FrameLightingStats& st = lighting.stats();
  const double updates = std::max(st.updates, 1);
  return {{"vertices", bakedVertices(scene)},
          {"through_operator", lighting.usesOperator()},
          {"gather_samples", lighting.usesOperator() ? 0 : settings.gatherSamples},
          {"trace_s", st.traceSeconds},
          {"updates", st.updates},
          {"shadow_rays_per_update", double(st.shadowRays) / updates},
          {"light_update_ms", median(updateMs)},
          {"shadow_ms", 1e3 * st.shadowSeconds / updates},
          {"products_or_gather_ms", 1e3 * st.gatherSeconds / updates},
          {"sh_product_ms", median(productMs)},
          {"ratio_lamp_to_sh_product", medianRatio(updateMs, productMs)},
          {"cube_shadow_ms", median(cubeMs)},
          {"cube_faces", renderer.lastFrame().localShadowMaps},
          {"frame", timing.json()}};
}

// The bounce operator of the in-process bake, as `prt bake --operator` builds it: its build time
// and packed size next to the bake's own time.
nlohmann::json addOperator(Scene& scene, const bake::BakeSettings& bs, double bakeSeconds) {
  bake::OperatorSettings os;
  os.samples = std::min(os.samples, bs.samples);
  const auto t0 = std::chrono::steady_clock::now();
  auto op = std::make_shared<BounceOperator>(bake::buildBounceOperator(scene, os, bs.bounces, bs.seed));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const size_t bytes = packOperator(*op).bytes.size();
  nlohmann::json j = {{"clusters", op->clusters},
                      {"vertex_sides", op->vertexSides},
                      {"cluster_entries", op->clusterRows.entries()},
                      {"vertex_entries", op->vertexRows.entries()},
                      {"bytes", bytes},
                      {"build_s", seconds},
                      {"surface_bake_s", bakeSeconds},
                      {"build_over_bake", seconds / std::max(bakeSeconds, 1e-9)}};
  scene.bounceOperator = std::move(op);
  return j;
}

}  // namespace

int main(int argc, char** argv) {
  prt::tuneHeap();  // as prt does (tools/main.cpp)
  std::string bakedPath, probesPath, jsonPath, gl = "osmesa";
  int width = 1920, height = 1080, frames = 12, samples = 128, probeDims = 16;
  int framesOnly = 0, sunOnly = 0, materialsOnly = 0, lampOnly = 0;
  std::vector<double> lampCentre;
  double lampRadius = 0.5;
  CLI::App app{"Render benchmark: ms per frame of full relighting next to the flat raster floor, light-update costs",
               "prt_bench_render"};
  app.add_option("--width", width, "Frame width")->check(CLI::Range(1, 16384))->capture_default_str();
  app.add_option("--height", height, "Frame height")->check(CLI::Range(1, 16384))->capture_default_str();
  app.add_option("--frames", frames, "Timed frames")->check(CLI::Range(1, 100000))->capture_default_str();
  app.add_option("--gl", gl, "OpenGL back end")
      ->check(CLI::IsMember({"osmesa", "egl"}, CLI::ignore_case))
      ->capture_default_str();
  CLI::Option* baked = app.add_option("--baked", bakedPath, "Baked scene (.glb) instead of baking the Cornell room");
  CLI::Option* probes = app.add_option("--probes", probesPath, "Probe grid (.vdb) baked with --baked");
  baked->needs(probes);
  probes->needs(baked);
  app.add_option("--samples", samples, "Hemisphere directions per vertex of the in-process bake")
      ->capture_default_str();
  app.add_option("--probe-dims", probeDims, "Probe lattice N³ of the in-process bake")
      ->check(CLI::Range(1, 512))
      ->capture_default_str();
  app.add_option("--frames-only", framesOnly, "1: skip the light-update part")
      ->check(CLI::IsMember({0, 1}))
      ->capture_default_str();
  app.add_option("--sun-only", sunOnly, "1: only the main frames and the sun-shadow frames")
      ->check(CLI::IsMember({0, 1}))
      ->capture_default_str();
  app.add_option("--materials-only", materialsOnly, "1: only the material frames (full glTF material, diffuse, flat)")
      ->check(CLI::IsMember({0, 1}))
      ->capture_default_str();
  app.add_option("--lamp-only", lampOnly, "1: only the moving lamp's light update next to the SH product alone")
      ->check(CLI::IsMember({0, 1}))
      ->capture_default_str();
  app.add_option("--lamp", lampCentre,
                 "Centre X,Y,Z of the moving lamp's circle (default: 0,1.45,0 in the bundled room, else the middle of "
                 "the scene's bounds)")
      ->expected(3)
      ->delimiter(',');
  app.add_option("--lamp-radius", lampRadius, "Radius of the moving lamp's circle about +Y")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--json", jsonPath, "Also write the results to this file");
  if (std::optional<int> status = bench::parseBenchOptions(app, "prt_bench_render", argc, argv)) return *status;
  try {
    // --- The scene: baked here or read from files ---------------------------------------------
    Scene scene;
    ProbeGrid grid;
    nlohmann::json operatorBuild;
    if (bakedPath.empty()) {
      scene = loadScene(PRT_SOURCE_DIR "/scenes/cornell_open.gltf");
      bake::BakeSettings bs;
      bs.samples = samples;
      bs.bounces = 1;
      bs.keepLowerOrder = true;
      const auto bake0 = std::chrono::steady_clock::now();
      bake::SurfaceTransfer t = bake::bakeSurface(scene, bs);
      const double bakeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - bake0).count();
      scene.transferBands = t.bands;
      bake::storeTransfer(scene, t.perMesh, t.perMeshDirect);                 // with the direct part (sun frames)
      scene.bakeRecord = bake::bakeRecord(bs, "cornell_open.gltf", "bench");  // bounces for the gather
      operatorBuild = addOperator(scene, bs, bakeSeconds);
      bake::ProbeSettings ps;
      ps.dims = glm::ivec3(probeDims);
      ps.samples = 256;
      ps.bounces = 1;
      grid = bake::bakeProbes(scene, t.perMeshLowerOrder, ps);
    } else {
      scene = loadScene(bakedPath);
      grid = readProbeGrid(probesPath);
    }
    const double duration = animationDuration(scene);

    // --- Full frames vs the raster floor, same run, interleaved ------------------------------
    render::GlContext context(render::parseGlBackend(gl), width, height);
    render::Renderer renderer(context, scene);
    renderer.setProbes(grid);
    render::CameraView view;
    if (!scene.cameras.empty()) {
      view = render::cameraView(scene.cameras[0]);
    } else {
      render::OrbitCamera orbit;
      view = render::orbitView(scene, orbit, double(width) / height);
    }
    glm::dvec3 centre(0.0, 1.45, 0.0);
    if (lampCentre.size() == 3) {
      centre = glm::dvec3(lampCentre[0], lampCentre[1], lampCentre[2]);
    } else if (!bakedPath.empty()) {
      centre = 0.5 * (glm::dvec3(scene.boundsMin) + glm::dvec3(scene.boundsMax));
    }
    if (lampOnly) {
      const nlohmann::json j = {{"device", context.description()},
                                {"lamp", lampLighting(renderer, scene, view, frames, centre, lampRadius)}};
      std::printf("%s\n", j.dump(2).c_str());
      if (!jsonPath.empty()) std::ofstream(jsonPath) << j.dump(2) << "\n";
      return 0;
    }
    if (materialsOnly) {
      const nlohmann::json j = {{"device", context.description()},
                                {"materials", materialFrames(context, scene, grid, view, frames)}};
      std::printf("%s\n", j.dump(2).c_str());
      if (!jsonPath.empty()) std::ofstream(jsonPath) << j.dump(2) << "\n";
      return 0;
    }
    // The baked instances alone: the same scene without a probe grid (receivers not drawn).
    render::Renderer bakedOnly(context, scene);
    Timing prtTiming, flatTiming, staticTiming, vertexTiming;
    std::vector<size_t> receiverPixels;
    render::FrameStats last;
    for (int i = -2; i < frames; ++i) {  // two warm-up frames: llvmpipe compiles shaders on first use
      render::Frame f;
      f.camera = view;
      f.time = i < 0 ? 0.0 : duration * i / frames;
      f.light = sky(360.0 * std::max(i, 0) / frames);
      render::Frame flatFrame = f, vertexFrame = f;
      flatFrame.shading = render::Shading::Flat;
      vertexFrame.probeLookup = render::ProbeLookup::PerVertex;
      // Every timed frame's image is dropped at once, so that all kinds allocate (and page in)
      // the same memory: keeping one kind's image alive while the next renders cost that one
      // fresh pages, ≈ 0.1 of a flat frame of CPU time here.
      for (int k = 0; k < 4; ++k) {
        switch ((k + std::max(i, 0)) % 4) {
          case 0:
            timedRender(renderer, f, i >= 0 ? &prtTiming : nullptr);
            last = renderer.lastFrame();
            break;
          case 1:
            timedRender(renderer, flatFrame, i >= 0 ? &flatTiming : nullptr);
            break;
          case 2:
            timedRender(renderer, vertexFrame, i >= 0 ? &vertexTiming : nullptr);
            break;
          default:
            timedRender(bakedOnly, f, i >= 0 ? &staticTiming : nullptr);
            break;
        }
      }
      // Pixels where the receiver is seen: those the receiver changes (untimed frames).
      if (i >= 0) receiverPixels.push_back(differingPixels(renderer.render(f), bakedOnly.render(f)));
    }
    std::sort(receiverPixels.begin(), receiverPixels.end());

    nlohmann::json j;
    j["device"] = context.description();
    j["frame"] = {{"width", width},
                  {"height", height},
                  {"frames", frames},
                  {"triangles", last.triangles},
                  {"receiver_triangles", last.receiverTriangles},
                  {"receiver_pixels", receiverPixels[receiverPixels.size() / 2]},
                  {"probes", grid.probeCount()},
                  {"bands", grid.bands},
                  {"prt", prtTiming.json()},
                  {"flat", flatTiming.json()},
                  {"prt_without_receivers", staticTiming.json()},
                  {"ratio", medianRatio(prtTiming.total, flatTiming.total)},
                  {"cpu_ratio", medianRatio(prtTiming.cpu, flatTiming.cpu)},
                  {"baked_ratio", medianRatio(staticTiming.total, flatTiming.total)},
                  {"baked_cpu_ratio", medianRatio(staticTiming.cpu, flatTiming.cpu)},
                  {"prt_per_vertex_lookup", vertexTiming.json()},
                  {"per_vertex_ratio", medianRatio(vertexTiming.total, flatTiming.total)},
                  {"per_vertex_cpu_ratio", medianRatio(vertexTiming.cpu, flatTiming.cpu)},
                  {"target_ratio", 1.5}};
    j["sun"] = sunShadows(renderer, scene, view, frames);
    j["materials"] = materialFrames(context, scene, grid, view, frames);
    if (sunOnly) {
      const std::string text = j.dump(2);
      std::printf("%s\n", text.c_str());
      if (!jsonPath.empty()) std::ofstream(jsonPath) << text << "\n";
      return 0;
    }
    j["receiver_closeup"] = receiverCloseup(renderer, bakedOnly, scene, width, height, frames);
    if (!framesOnly) j.update(lightUpdates(context, scene, view));
    if (!framesOnly) j["frame_lighting"] = frameLighting(renderer, scene, view, frames, false);
    if (!framesOnly) j["lamp"] = lampLighting(renderer, scene, view, frames, centre, lampRadius);
    if (!framesOnly && scene.bounceOperator) {
      j["frame_lighting_operator"] = frameLighting(renderer, scene, view, frames, true);
      if (!operatorBuild.is_null()) j["operator_build"] = operatorBuild;
    }
    const std::string text = j.dump(2);
    std::printf("%s\n", text.c_str());
    if (!jsonPath.empty()) std::ofstream(jsonPath) << text << "\n";
    return 0;
  } catch (const Error& e) {
    std::fprintf(stderr, "prt_bench_render: %s\n", e.what());
    return 1;
  }
}
