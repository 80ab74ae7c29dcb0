#include "render_command.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "light_options.h"
#include "prt/error.h"
#include "prt/image.h"
#include "prt/probe_grid.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "prt/scene.h"

namespace prt::tools {

namespace {

struct RenderArgs {
  std::string baked, output = "out/frame_%04d.exr", frames = "0-0", size = "640x360", camera, gl = "osmesa";
  LightOptions light;
  double envRotateEnd = std::nan("");
  bool png = false;
  double exposure = 0.0;
  double orbitAzimuth = 0.0, orbitElevation = 20.0, orbitYfov = 45.0;
  bool quiet = false;
  std::string probes;  // probe grid (.vdb) lighting the receivers
  double fps = 24.0;   // frame f is at time f / fps of the scene's animations
};

RenderArgs args;

// Expands the one printf-style integer field (%d, %04d) of a frame path pattern.
std::string framePath(const std::string& pattern, int frame) {
  size_t p = pattern.find('%');
  if (p == std::string::npos) return pattern;
  size_t e = pattern.find('d', p);
  if (e == std::string::npos) throw Error(cat("-o ", pattern, ": expected a frame field like %04d"));
  std::string spec = pattern.substr(p, e - p + 1);
  for (char c : spec.substr(1, spec.size() - 2))
    if (c < '0' || c > '9') throw Error(cat("-o ", pattern, ": bad frame field '", spec, "'"));
  char buf[32];
  std::snprintf(buf, sizeof buf, spec.c_str(), frame);
  return pattern.substr(0, p) + buf + pattern.substr(e + 1);
}

}  // namespace

CLI::App* addRenderCommand(CLI::App& app) {
  CLI::App* r = app.add_subcommand("render", "Render relit frames of a baked scene headlessly (EXR, PNG)");
  r->add_option("baked", args.baked, "Baked scene (.glb from prt bake)")->required();
  r->add_option("-o,--output", args.output, "Frame path pattern (.exr), e.g. out/frame_%04d.exr")->capture_default_str();
  r->add_option("--frames", args.frames, "Frame range A-B (inclusive)")->capture_default_str();
  r->add_option("--size", args.size, "Image size WxH")->capture_default_str();
  r->add_option("--camera", args.camera, "glTF camera name (default: the first camera, else an orbit)");
  r->add_option("--orbit-azimuth", args.orbitAzimuth, "Orbit camera azimuth, degrees about +Y")->capture_default_str();
  r->add_option("--orbit-elevation", args.orbitElevation, "Orbit camera elevation, degrees")->capture_default_str();
  r->add_option("--gl", args.gl, "OpenGL back end: osmesa or egl")->capture_default_str();
  r->add_option("--probes", args.probes, "Probe grid (.vdb from prt bake --probes) lighting the receivers");
  r->add_option("--fps", args.fps, "Frames per second: frame f shows the scene's animations at time f/fps")
      ->capture_default_str();
  addLightOptions(*r, args.light);
  r->add_option("--env-rotate-end", args.envRotateEnd,
                "Environment rotation at the last frame, degrees (linear from --env-rotate)");
  r->add_flag("--png", args.png, "Also write tone-mapped sRGB PNGs next to the EXRs");
  r->add_option("--exposure", args.exposure, "PNG exposure in stops")->capture_default_str();
  r->add_flag("-q,--quiet", args.quiet, "No per-frame lines, no summary");
  return r;
}

void runRenderCommand() {
  const RenderArgs& a = args;
  int first = 0, last = 0, width = 0, height = 0;
  if (std::sscanf(a.frames.c_str(), "%d-%d", &first, &last) != 2 || first < 0 || last < first)
    throw Error(cat("--frames ", a.frames, ": expected A-B with 0 <= A <= B"));
  if (std::sscanf(a.size.c_str(), "%dx%d", &width, &height) != 2 || width < 1 || height < 1 || width > 16384 ||
      height > 16384)
    throw Error(cat("--size ", a.size, ": expected WxH, each 1..16384"));
  if (!(a.fps > 0.0) || !std::isfinite(a.fps)) throw Error(cat("--fps ", a.fps, ": expected a positive number"));
  render::GlBackend backend = render::parseGlBackend(a.gl);
  std::filesystem::path dir = std::filesystem::path(framePath(a.output, first)).parent_path();
  if (!dir.empty() && !std::filesystem::is_directory(dir))
    throw Error(cat(a.output, ": directory '", dir.string(), "' does not exist"));

  Scene scene = loadScene(a.baked);
  if (scene.transferBands == 0) throw Error(cat(a.baked, ": holds no baked transfer (run prt bake first)"));
  const int bands = scene.transferBands;
  // The environment is projected once; each frame only rotates it (exact, per band).
  LightOptions envOnly = a.light, sunOnly = a.light;
  envOnly.sunDir.clear();
  envOnly.envRotate = 0.0;
  sunOnly.env.clear();
  if (a.light.env.empty() && a.light.sunDir.empty()) throw Error("no lighting: give --env MAP and/or --sun-dir X,Y,Z");
  sh::ShRgb env = a.light.env.empty() ? sh::ShRgb(bands) : buildLight(envOnly, bands);
  sh::ShRgb sun = a.light.sunDir.empty() ? sh::ShRgb(bands) : buildLight(sunOnly, bands);

  render::CameraView view;
  if (!a.camera.empty() || !scene.cameras.empty()) {
    const Camera* cam = nullptr;
    for (const Camera& c : scene.cameras)
      if (a.camera.empty() || c.name == a.camera) {
        cam = &c;
        break;
      }
    if (!cam) throw Error(cat(a.baked, ": no camera named '", a.camera, "'"));
    view = render::cameraView(*cam);
  } else {
    render::OrbitCamera orbit;
    orbit.azimuthDegrees = a.orbitAzimuth;
    orbit.elevationDegrees = a.orbitElevation;
    view = render::orbitView(scene, orbit, double(width) / height);
  }

  render::GlContext context(backend, width, height);
  render::Renderer renderer(context, scene);
  ProbeGrid probes;
  if (!a.probes.empty()) {
    probes = readProbeGrid(a.probes);
    renderer.setProbes(probes);
  }
  if (!a.quiet)
    for (const std::string& w : renderer.warnings()) std::fprintf(stderr, "prt: warning: %s\n", w.c_str());
  double drawMs = 0.0, lightMs = 0.0;
  const double rot0 = a.light.envRotate, rot1 = std::isnan(a.envRotateEnd) ? rot0 : a.envRotateEnd;
  for (int f = first; f <= last; ++f) {
    auto t0 = std::chrono::steady_clock::now();
    double s = last > first ? double(f - first) / double(last - first) : 0.0;
    sh::ShRgb light = sh::Rotation(bands, sh::rotationY(rot0 + s * (rot1 - rot0))).apply(env);
    light += sun;
    auto t1 = std::chrono::steady_clock::now();
    render::Frame frame;
    frame.camera = view;
    frame.light = light;
    frame.time = f / a.fps;
    frame.width = width;
    frame.height = height;
    ImageRgb image = renderer.render(frame);
    std::string path = framePath(a.output, f);
    writeExr(path, image);
    if (a.png) writePng(std::filesystem::path(path).replace_extension(".png").string(), image, float(a.exposure));
    lightMs += std::chrono::duration<double, std::milli>(t1 - t0).count() + renderer.lastFrame().lightMs;
    drawMs += renderer.lastFrame().drawMs + renderer.lastFrame().readbackMs;
    if (!a.quiet) std::fprintf(stderr, "frame %d -> %s (%.1f ms)\n", f, path.c_str(), renderer.lastFrame().drawMs);
  }
  const int n = last - first + 1;
  if (!a.quiet)
    std::fprintf(stderr, "prt render: %d frames %dx%d on %s; %.2f ms/frame (draw + readback), %.3f ms per light update\n",
                 n, width, height, context.description().c_str(), drawMs / n, lightMs / n);
}

}  // namespace prt::tools
