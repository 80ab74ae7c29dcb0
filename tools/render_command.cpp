#include "render_command.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "frame_outputs.h"
#include "light_options.h"
#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/image.h"
#include "prt/light_rig.h"
#include "prt/probe_grid.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "prt/scene.h"

namespace prt::tools {

namespace {

struct RenderArgs {
  std::string baked, output = "out/frame_%04d.exr", frames = "0-0", size = "640x360", camera, gl = "osmesa";
  LightOptions light;
  bool png = false;
  double exposure = 0.0;
  double fps = 0.0;  // 0: the rig's fps, else 24; frame f is at time f / fps of the animations
  std::string probes;  // probe grid (.vdb) lighting the receivers
  std::string exrCompression = "zip";
  std::string mp4, contactSheet;
  int sheetColumns = 0, sheetTile = 192;
  double orbitAzimuth = 0.0, orbitElevation = 20.0, orbitYfov = 45.0;
  bool quiet = false;
  CLI::Option* framesOption = nullptr;
  CLI::Option* fpsOption = nullptr;
};

RenderArgs args;

constexpr double kDefaultFps = 24.0;

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

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

CLI::App* addRenderCommand(CLI::App& app) {
  CLI::App* r = app.add_subcommand("render", "Render relit frames of a baked scene headlessly (EXR, PNG, MP4)");
  r->add_option("baked", args.baked, "Baked scene (.glb from prt bake)")->required();
  r->add_option("-o,--output", args.output, "Frame path pattern (.exr), e.g. out/frame_%04d.exr")->capture_default_str();
  args.framesOption = r->add_option("--frames", args.frames,
                                    "Frame range A-B (inclusive); default 0-0, or the --rig's keyframe range")
                          ->capture_default_str();
  r->add_option("--size", args.size, "Image size WxH")->capture_default_str();
  r->add_option("--camera", args.camera, "glTF camera name (default: the first camera, else an orbit)");
  r->add_option("--orbit-azimuth", args.orbitAzimuth, "Orbit camera azimuth, degrees about +Y")->capture_default_str();
  r->add_option("--orbit-elevation", args.orbitElevation, "Orbit camera elevation, degrees")->capture_default_str();
  r->add_option("--gl", args.gl, "OpenGL back end: osmesa or egl")->capture_default_str();
  addLightOptions(*r, args.light, /*animated=*/true);
  r->add_option("--exr-compression", args.exrCompression, "EXR compression, all lossless: zip, piz or none (fastest)")
      ->capture_default_str();
  r->add_flag("--png", args.png, "Also write tone-mapped sRGB PNGs next to the EXRs");
  r->add_option("--exposure", args.exposure, "Exposure in stops for PNG, MP4 and contact sheet")->capture_default_str();
  r->add_option("--mp4", args.mp4, "Also encode the frames as H.264 MP4 with ffmpeg (must be on PATH)");
  args.fpsOption = r->add_option("--fps", args.fps,
                "Frames per second: frame f shows the scene's animations at time f/fps; also the --mp4 rate "
                "(default: the rig's fps, else 24)");
  r->add_option("--probes", args.probes, "Probe grid (.vdb from prt bake --probes) lighting the receivers");
  r->add_option("--contact-sheet", args.contactSheet, "Also write a PNG grid of all frames, downscaled");
  r->add_option("--sheet-columns", args.sheetColumns, "Contact sheet columns (0 = about square)")->capture_default_str();
  r->add_option("--sheet-tile", args.sheetTile, "Contact sheet: largest tile side in pixels")->capture_default_str();
  r->add_flag("-q,--quiet", args.quiet, "No per-frame lines, no summary");
  return r;
}

void runRenderCommand() {
  const RenderArgs& a = args;
  const auto tStart = std::chrono::steady_clock::now();
  int first = 0, last = 0, width = 0, height = 0;
  if (std::sscanf(a.size.c_str(), "%dx%d", &width, &height) != 2 || width < 1 || height < 1 || width > 16384 ||
      height > 16384)
    throw Error(cat("--size ", a.size, ": expected WxH, each 1..16384"));
  render::GlBackend backend = render::parseGlBackend(a.gl);
  if (!std::isfinite(a.exposure)) throw Error("--exposure: not a finite number");
  if (a.fpsOption->count() > 0 && !(std::isfinite(a.fps) && a.fps > 0)) throw Error(cat("--fps ", a.fps, ": must be > 0"));
  if (a.sheetColumns < 0) throw Error(cat("--sheet-columns ", a.sheetColumns, ": must be >= 0"));
  if (a.sheetTile < 1) throw Error(cat("--sheet-tile ", a.sheetTile, ": must be >= 1"));
  ExrCompression compression = ExrCompression::Zip;
  if (a.exrCompression == "none")
    compression = ExrCompression::None;
  else if (a.exrCompression == "piz")
    compression = ExrCompression::Piz;
  else if (a.exrCompression != "zip")
    throw Error(cat("--exr-compression ", a.exrCompression, ": expected zip, piz or none"));

  // Lighting first (a bad rig or map fails before any GL work). A rig file's keyframe range is
  // the default frame range; the shortcuts' START:END need the range to place their keys.
  std::optional<LightRig> rig;
  if (!a.light.rig.empty()) rig = buildRig(a.light, 0, 0);
  if (a.framesOption->count() > 0 || !rig || !rig->animated()) {
    if (std::sscanf(a.frames.c_str(), "%d-%d", &first, &last) != 2 || first < 0 || last < first)
      throw Error(cat("--frames ", a.frames, ": expected A-B with 0 <= A <= B"));
  } else {
    auto [lo, hi] = rig->keyRange();
    first = std::max(0, int(std::floor(lo)));
    last = std::max(first, int(std::ceil(hi)));
  }
  if (!rig) rig = buildRig(a.light, first, last);

  std::filesystem::path dir = std::filesystem::path(framePath(a.output, first)).parent_path();
  if (!dir.empty() && !std::filesystem::is_directory(dir))
    throw Error(cat(a.output, ": directory '", dir.string(), "' does not exist"));
  std::unique_ptr<VideoEncoder> video;
  if (!a.mp4.empty()) video = std::make_unique<VideoEncoder>(a.mp4);  // ffmpeg missing: fail now
  if (!a.contactSheet.empty()) AtomicFile probe(a.contactSheet);     // unwritable: fail now
  const double fps = a.fpsOption->count() > 0 ? a.fps : rig->fps.value_or(kDefaultFps);

  Scene scene = loadScene(a.baked);
  if (scene.transferBands == 0) throw Error(cat(a.baked, ": holds no baked transfer (run prt bake first)"));
  const int bands = scene.transferBands;

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
  const int n = last - first + 1;
  std::optional<ContactSheet> sheet;
  if (!a.contactSheet.empty()) sheet.emplace(width, height, n, a.sheetColumns, a.sheetTile);
  if (video) video->start(width, height, fps);

  // Maps are projected once, here; a frame then costs a rotation and the analytic lights.
  const auto tPrepare = std::chrono::steady_clock::now();
  rig->prepare(bands);
  const double prepareMs = msSince(tPrepare);
  double lightMs = 0.0, drawMs = 0.0, readbackMs = 0.0, writeMs = 0.0, encodeMs = 0.0;
  for (int f = first; f <= last; ++f) {
    auto t0 = std::chrono::steady_clock::now();
    sh::ShRgb light = rig->evaluate(f, bands);
    const double rigMs = msSince(t0);
    render::Frame frame;
    frame.camera = view;
    frame.light = light;
    frame.time = f / fps;
    frame.width = width;
    frame.height = height;
    ImageRgb image = renderer.render(frame);
    // The light update: the rig's SH plus, with probes, relighting and uploading the grid.
    const double frameLightMs = rigMs + renderer.lastFrame().lightMs;
    auto t1 = std::chrono::steady_clock::now();
    std::string path = framePath(a.output, f);
    writeExr(path, image, compression);
    if (a.png) writePng(std::filesystem::path(path).replace_extension(".png").string(), image, float(a.exposure));
    if (sheet) sheet->add(image);
    const double frameWriteMs = msSince(t1);
    auto t2 = std::chrono::steady_clock::now();
    if (video) video->addFrame(image, float(a.exposure));
    encodeMs += msSince(t2);
    lightMs += frameLightMs;
    drawMs += renderer.lastFrame().drawMs;
    readbackMs += renderer.lastFrame().readbackMs;
    writeMs += frameWriteMs;
    if (!a.quiet)
      std::fprintf(stderr, "frame %d -> %s: light %.3f ms, draw %.1f ms, readback %.1f ms, write %.1f ms\n", f,
                   path.c_str(), frameLightMs, renderer.lastFrame().drawMs, renderer.lastFrame().readbackMs,
                   frameWriteMs);
  }
  auto tEnd = std::chrono::steady_clock::now();
  if (video) video->finish();
  encodeMs += msSince(tEnd);
  if (sheet) sheet->write(a.contactSheet, float(a.exposure));
  if (a.quiet) return;
  std::fprintf(stderr,
               "prt render: %d frame%s %dx%d written (%s .. %s)%s on %s\n"
               "  %.2f ms/frame draw + %.2f ms/frame readback, %.3f ms per light update (%zu lights, %d bands, "
               "window %s; maps projected once in %.1f ms), %.2f ms/frame writing\n",
               n, n == 1 ? "" : "s", width, height, framePath(a.output, first).c_str(), framePath(a.output, last).c_str(),
               a.png ? " + PNG" : "", context.description().c_str(), drawMs / n, readbackMs / n, lightMs / n,
               rig->lights.size(), bands, sh::windowName(rig->window), prepareMs, writeMs / n);
  if (video)
    std::fprintf(stderr, "  video %s: %d frames at %g fps, %.2f ms/frame encoding (%s)\n", a.mp4.c_str(), n, fps,
                 encodeMs / n, video->ffmpeg().c_str());
  if (sheet)
    std::fprintf(stderr, "  contact sheet %s: %d columns of %dx%d tiles (1/%d)\n", a.contactSheet.c_str(),
                 sheet->columns(), sheet->tileWidth(), sheet->tileHeight(), sheet->factor());
  std::fprintf(stderr, "  total %.2f s (%.1f ms/frame)\n", msSince(tStart) / 1000.0, msSince(tStart) / n);
}

}  // namespace prt::tools
