#include "render_command.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <deque>
#include <exception>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <tuple>
#include <vector>

#include "cli_checks.h"
#include "frame_outputs.h"
#include "light_options.h"
#include "prt/atomic_file.h"
#include "prt/bake/bounce_operator.h"
#include "prt/bake/frame_lighting.h"
#include "prt/bake/local_lights.h"
#include "prt/error.h"
#include "prt/image.h"
#include "prt/light_rig.h"
#include "prt/probe_grid.h"
#include "prt/relight.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"
#include "prt/scene.h"

namespace prt::tools {

namespace {

// Shadow rays per direct light and vertex for the light their gathered bounce starts from: the
// bounce averages it over hundreds of hits, so its noise does not show (docs/render.md).
constexpr int kBounceShadowSamples = 4;
// Shadow rays per area light or emissive surface and vertex for the lights inside the scene
// (prt relight's default --shadow-samples): an emissive surface's light is drawn from them.
constexpr int kLocalShadowSamples = 64;

constexpr double kDefaultFps = 24.0;
// Frame numbers stay below INT_MAX so that f + 1, the rig's frames and %d never overflow.
constexpr int64_t kMaxFrame = std::numeric_limits<int>::max() - 1;
// A rig's keyframe range is rendered by default only up to this many frames; a longer sequence
// (a stray key at frame 1e9) needs --frames, so a typo cannot start a render that never ends.
constexpr int64_t kMaxDefaultFrames = 100000;
// Frames and contact sheets: each side at most the GL renderbuffer limit of llvmpipe, and at
// most 8192² pixels, about 60 bytes each in GL buffers, read-back and encoding (≈ 4 GB).
constexpr int kMaxSide = 16384;
constexpr int64_t kMaxPixels = int64_t(8192) * 8192;

// A whole non-negative decimal number: digits only ("12", not "+12", "12x" or " 12").
std::optional<int64_t> parseWhole(std::string_view text) {
  uint64_t v = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size() || v > uint64_t(kMaxFrame))
    return std::nullopt;
  return int64_t(v);
}

// --frames A-B (inclusive) or A. Throws CLI::ValidationError: a usage error, with the whole
// message (CLI11 would put the option's name in front of a validator's).
FrameRange parseFrames(const std::string& text) {
  const size_t dash = text.find('-');
  std::optional<int64_t> a = parseWhole(std::string_view(text).substr(0, dash));
  std::optional<int64_t> b = dash == std::string::npos ? a : parseWhole(std::string_view(text).substr(dash + 1));
  if (!a || !b)
    throw CLI::ValidationError(cat("--frames ", text, ": expected A-B or A, whole frame numbers 0..", kMaxFrame));
  if (*b < *a) throw CLI::ValidationError(cat("--frames ", text, ": the last frame comes before the first"));
  return {*a, *b};
}

// --size WxH. Throws CLI::ValidationError, as parseFrames.
std::pair<int, int> parseSize(const std::string& text) {
  const size_t x = text.find('x');
  std::optional<int64_t> w = parseWhole(std::string_view(text).substr(0, x));
  std::optional<int64_t> h = x == std::string::npos ? std::nullopt : parseWhole(std::string_view(text).substr(x + 1));
  if (!w || !h || *w < 1 || *h < 1 || *w > kMaxSide || *h > kMaxSide)
    throw CLI::ValidationError(cat("--size ", text, ": expected WxH, each 1..", kMaxSide));
  if (*w * *h > kMaxPixels)
    throw CLI::ValidationError(
        cat("--size ", text, ": ", *w * *h, " pixels, more than the ", kMaxPixels, " (8192x8192) allowed"));
  return {int(*w), int(*h)};
}

// Writes frames on a thread of its own, in order, while the next frame renders: a frame's EXR,
// PNG, contact-sheet tile and video frame are one job. At most `maxQueued` jobs wait (each holds
// a frame). The first job that throws stops the writer: push() and finish() rethrow its error on
// the rendering thread, so the command stops with that one message; files already written stay
// whole (each is written atomically). Destroyed before finish() (the render failed), it drops
// the frames still queued.
class FrameWriter {
 public:
  explicit FrameWriter(size_t maxQueued) : maxQueued_(maxQueued), thread_([this] { run(); }) {}
  ~FrameWriter() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
      jobs_.clear();
    }
    changed_.notify_all();
    thread_.join();
  }
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;

  void push(std::function<void()> job) {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return jobs_.size() < maxQueued_ || error_; });
    if (error_) std::rethrow_exception(error_);
    jobs_.push_back(std::move(job));
    changed_.notify_all();
  }
  /// Waits until every job ran; rethrows the first error.
  void finish() {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return (jobs_.empty() && !busy_) || error_; });
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void run() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      changed_.wait(lock, [&] { return !jobs_.empty() || stop_; });
      if (stop_ || error_) return;
      std::function<void()> job = std::move(jobs_.front());
      jobs_.pop_front();
      busy_ = true;
      changed_.notify_all();
      lock.unlock();
      std::exception_ptr error;
      try {
        job();
      } catch (...) {
        error = std::current_exception();
      }
      lock.lock();
      busy_ = false;
      if (error) error_ = error;
      changed_.notify_all();
      if (error_) return;
    }
  }

  const size_t maxQueued_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::function<void()>> jobs_;
  bool busy_ = false, stop_ = false;
  std::exception_ptr error_;
  std::thread thread_;  // last: starts once the members above exist
};

// Without --frames, a rig with keyframes renders its keyframe range, rounded outwards and cut
// at frame 0. The range is computed in double: a key at 1e12 must not wrap an int.
FrameRange rigFrames(const LightRig& rig, const std::string& rigPath) {
  auto [lo, hi] = rig.keyRange();
  const double first = std::max(0.0, std::floor(lo)), last = std::max(first, std::ceil(hi));
  if (!(last - first + 1 <= double(kMaxDefaultFrames)))
    throw Error(cat(rigPath, ": keyframes run from frame ", lo, " to ", hi, ", ", last - first + 1,
                    " frames; more than ", kMaxDefaultFrames, " are rendered only with an explicit --frames A-B"));
  if (last > double(kMaxFrame))
    throw Error(cat(rigPath, ": keyframes beyond frame ", kMaxFrame, " (up to ", hi, "); give --frames A-B"));
  return {int64_t(first), int64_t(last)};
}

// The -o pattern: a name with at most one frame field, %d or %0Nd, in the file name. A bad
// pattern is a usage error.
class FramePattern {
 public:
  explicit FramePattern(std::string pattern) : pattern_(std::move(pattern)) {
    const size_t p = pattern_.find('%');
    if (p == std::string::npos) return;
    // '%', an optional zero-padded width (0 followed by 1-2 digits), 'd'.
    size_t d = p + 1;
    while (d < pattern_.size() && d - p <= 3 && std::isdigit(static_cast<unsigned char>(pattern_[d]))) ++d;
    const std::string width = pattern_.substr(p + 1, d - p - 1);
    if (d >= pattern_.size() || pattern_[d] != 'd' || !(width.empty() || (width.size() >= 2 && width[0] == '0')))
      throw UsageError(
          cat("-o ", pattern_, ": bad frame field '", pattern_.substr(p, d - p + 1), "': use %d or %0Nd, e.g. %04d"));
    if (pattern_.find('%', d) != std::string::npos)
      throw UsageError(cat("-o ", pattern_, ": more than one '%' (one frame field, %d or %0Nd)"));
    if (pattern_.find('/', d) != std::string::npos)
      throw UsageError(cat("-o ", pattern_, ": the frame field must be in the file name, not in a folder"));
    prefix_ = pattern_.substr(0, p);
    suffix_ = pattern_.substr(d + 1);
    width_ = width.empty() ? 0 : std::stoi(width);
    hasField_ = true;
  }

  bool hasField() const { return hasField_; }
  const std::string& text() const { return pattern_; }

  std::string path(int64_t frame) const {
    if (!hasField_) return pattern_;
    std::string digits = std::to_string(frame);
    if (int(digits.size()) < width_) digits.insert(0, size_t(width_) - digits.size(), '0');
    return prefix_ + digits + suffix_;
  }

 private:
  std::string pattern_, prefix_, suffix_;
  int width_ = 0;
  bool hasField_ = false;
};

// An output's folder need not exist yet (it is created before the first frame), but the
// nearest existing folder above it must be a writable folder. `what` names the option.
void checkFolderFor(const std::string& what, const std::filesystem::path& file) {
  std::filesystem::path dir = file.parent_path();
  std::error_code ec;
  while (!dir.empty() && !std::filesystem::exists(dir, ec)) dir = dir.parent_path();
  const std::string shown = dir.empty() ? "." : dir.string();
  if (!std::filesystem::is_directory(shown, ec)) throw Error(cat(what, ": '", shown, "' is not a folder"));
  if (::access(shown.c_str(), W_OK | X_OK) != 0)
    throw Error(cat(what, ": cannot write in folder '", shown, "' (", std::strerror(errno), ")"));
}

void createFolderFor(const std::string& what, const std::filesystem::path& file) {
  const std::filesystem::path dir = file.parent_path();
  std::error_code ec;
  if (!dir.empty()) std::filesystem::create_directories(dir, ec);
  if (ec) throw Error(cat(what, ": cannot create folder '", dir.string(), "' (", ec.message(), ")"));
}

// Checks -o before any work: a frame field when there is more than one frame and the .exr
// extension (usage errors), a folder that can be written or created.
void checkOutput(const FramePattern& out, const FrameRange& frames) {
  const std::string what = cat("-o ", out.text());
  if (!out.hasField() && frames.count() > 1)
    throw UsageError(cat(what, ": ", frames.count(),
                         " frames need a frame-number field in the name, "
                         "e.g. frame_%04d.exr (only a single frame may have a plain name)"));
  const std::filesystem::path first = out.path(frames.first);
  std::string ext = first.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext != ".exr") throw UsageError(cat(what, ": expected an .exr file name (--png writes PNGs next to the EXRs)"));
  checkFolderFor(what, first);
}

// The orbit options (their ranges checked by CLI11, the camera excluding them).
render::OrbitCamera orbitCamera(const RenderArgs& a) {
  render::OrbitCamera orbit;
  orbit.azimuthDegrees = a.orbitAzimuth;
  orbit.elevationDegrees = a.orbitElevation;
  orbit.yfovDegrees = a.orbitFov;
  orbit.distance = a.orbitDistance;
  if (!a.orbitTarget.empty())
    orbit.target = glm::vec3(glm::dvec3(a.orbitTarget[0], a.orbitTarget[1], a.orbitTarget[2]));
  return orbit;
}

struct ChosenCamera {
  render::CameraView view;
  std::string description;  // for the summary
};

// --camera NAME: that glTF camera. Any --orbit-* option: the orbit. Neither: the file's first
// camera, else the orbit.
ChosenCamera chooseCamera(const RenderArgs& a, const render::OrbitCamera& orbit, const Scene& scene, double aspect) {
  if (!a.camera.empty() || (a.orbitOption.empty() && !scene.cameras.empty())) {
    auto cam = std::find_if(scene.cameras.begin(), scene.cameras.end(),
                            [&](const Camera& c) { return a.camera.empty() || c.name == a.camera; });
    if (cam == scene.cameras.end()) throw Error(cat(a.baked, ": no camera named '", a.camera, "'"));
    const std::string lens = cam->perspective ? cat("vertical fov ", glm::degrees(cam->yfov), " deg")
                                              : cat("orthographic, ymag ", cam->ymag);
    return {render::cameraView(*cam), cat("glTF camera '", cam->name, "' (node ", cam->node, ", ", lens, ")")};
  }
  const render::CameraView view = render::orbitView(scene, orbit, aspect);
  const glm::dvec3 target = render::orbitTarget(scene, orbit);
  const double distance = glm::length(glm::dvec3(view.cameraToWorld[3]) - target);
  return {view, cat("orbit (target ", target.x, ",", target.y, ",", target.z, ", distance ", distance, ", azimuth ",
                    orbit.azimuthDegrees, ", elevation ", orbit.elevationDegrees, ", vertical fov ", orbit.yfovDegrees,
                    " deg", a.orbitOption.empty() ? "; the file has no camera" : "", ")")};
}

// A probe grid baked for another scene still renders, but wrongly: the bake's scene name and
// seed, stored in both files, must agree (a warning if not); bands must match (an error).
std::vector<std::string> checkProbesMatch(const ProbeGrid& grid, const Scene& scene, const RenderArgs& a) {
  if (grid.bands != scene.transferBands)
    throw Error(cat(a.probes, ": ", grid.bands, " bands, but ", a.baked, " is baked with ", scene.transferBands,
                    " (bake the surface and the probes together, with one --bands)"));
  // A .glb without a record (baked before records existed, or made by hand) says nothing.
  const std::optional<BakeRecord>& record = scene.bakeRecord;
  if (!record || grid.info.scene.empty()) return {};
  if (record->scene == grid.info.scene && record->seed == grid.info.seed) return {};
  return {cat(a.probes, " was baked from '", grid.info.scene, "' (seed ", grid.info.seed, "), ", a.baked, " from '",
              record->scene, "' (seed ", record->seed, "): the probes may belong to another scene or bake")};
}

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// --camera and the orbit camera's options: any --orbit-* option selects the orbit.
void addCameraOptions(CLI::App& r, RenderArgs& a) {
  CLI::Option* camera =
      r.add_option("--camera", a.camera, "glTF camera name (default: the first camera, else the orbit camera)");
  const std::vector<CLI::Option*> orbit = {
      r.add_option("--orbit-azimuth", a.orbitAzimuth, "Orbit camera azimuth, degrees about +Y (0: looking down -Z)")
          ->check(finite())
          ->capture_default_str(),
      r.add_option("--orbit-elevation", a.orbitElevation,
                   "Orbit camera elevation, degrees (-89..89: straight up or down leaves the view's roll undefined)")
          ->check(finiteIn(-89.0, 89.0))
          ->capture_default_str(),
      r.add_option(
           "--orbit-distance", a.orbitDistance,
           "Orbit camera distance from the target (default: the sphere around where the geometry is fills the view)")
          ->check(finitePositive()),
      r.add_option("--orbit-target", a.orbitTarget, "Point the orbit camera looks at X,Y,Z (default: bounds centre)")
          ->delimiter(',')
          ->expected(3)
          ->check(finite()),
      r.add_option("--orbit-fov", a.orbitFov, "Orbit camera vertical field of view, degrees")
          ->check(finiteIn(0.0, 180.0, /*open=*/true))
          ->capture_default_str()};
  for (CLI::Option* o : orbit) {
    o->group("Camera (any --orbit-* option selects the orbit camera)");
    o->excludes(camera);
    o->each([&a, name = o->get_name()](const std::string&) {
      if (a.orbitOption.empty()) a.orbitOption = name;
    });
  }
}

// The frame as rendered: supersampled frames are averaged down before they are written.
struct RenderSize {
  int64_t width = 0, height = 0;
};

RenderSize renderSize(const RenderArgs& a) {
  const RenderSize size{int64_t(a.width) * a.supersample, int64_t(a.height) * a.supersample};
  if (size.width > kMaxSide || size.height > kMaxSide || size.width * size.height > kMaxPixels)
    throw UsageError(cat("--supersample ", a.supersample, " with --size ", a.width, "x", a.height, ": renders ",
                         size.width, "x", size.height, ", more than the ", kMaxSide,
                         " a side and 8192x8192 pixels allowed"));
  return size;
}

// The lighting and the frames it lights, first (a bad rig or map fails before any GL work). A
// rig file's keyframe range is the default frame range; the shortcuts' START:END need the range
// to place their keys.
struct FrameLights {
  LightRig rig;
  FrameRange frames;
  bool localPerPixel = false;  // point, spot and area lights inside the scene lit per pixel
};

// `lightsInScene`: the scene's own lights light it, so no lighting option is needed.
FrameLights frameLights(const RenderArgs& a, bool lightsInScene) {
  std::optional<LightRig> rig;
  if (!a.light.rig.empty()) rig = buildRig(a.light, 0, 0, lightsInScene);
  const FrameRange frames =
      a.frames || !rig || !rig->animated() ? a.frames.value_or(FrameRange{}) : rigFrames(*rig, a.light.rig);
  if (!rig) rig = buildRig(a.light, int(frames.first), int(frames.last), lightsInScene);
  if (a.background == Background::Sky) {
    size_t maps = 0, caps = 0;
    for (const RigLight& l : rig->lights) {
      maps += l.type == RigLight::Type::Environment;
      caps += l.type == RigLight::Type::Sun || l.type == RigLight::Type::Disk;
    }
    render::checkBackgroundSize(cat("--background sky: ", a.light.rig.empty() ? "the lights" : a.light.rig), maps,
                                caps);
  }
  if (a.materials == render::MaterialShading::Full) {
    size_t maps = 0;
    for (const RigLight& l : rig->lights) maps += l.type == RigLight::Type::Environment;
    if (maps > size_t(render::kMaxReflectedMaps))
      throw Error(cat(a.light.rig.empty() ? "the lights" : a.light.rig, ": ", maps, " environment maps, at most ",
                      render::kMaxReflectedMaps, " can be reflected (--materials diffuse reflects none)"));
  }
  return {std::move(*rig), frames};
}

// Where the frames go: the -o pattern, and the video and contact sheet if asked for.
struct Outputs {
  FramePattern pattern;
  std::unique_ptr<VideoEncoder> video;
  std::optional<ContactSheet> sheet;
  double writeMs = 0.0, encodeMs = 0.0;  // summed over the frames
};

// Checks every output before any work (ffmpeg missing fails now).
Outputs checkOutputs(const RenderArgs& a, const FrameRange& frames) {
  Outputs out{FramePattern(a.output)};
  checkOutput(out.pattern, frames);
  if (!a.mp4.empty()) {
    out.video = std::make_unique<VideoEncoder>(a.mp4);
    checkFolderFor(cat("--mp4 ", a.mp4), a.mp4);
  }
  if (!a.contactSheet.empty()) {
    const ContactSheet::Layout sheet =
        ContactSheet::layout(a.width, a.height, frames.count(), a.sheetColumns, a.sheetTile);
    if (sheet.width > kMaxSide || sheet.height > kMaxSide || sheet.width * sheet.height > kMaxPixels)
      throw UsageError(cat("--contact-sheet ", a.contactSheet, ": ", frames.count(), " frames make a ", sheet.width,
                           "x", sheet.height, " sheet, over ", kMaxSide, " pixels a side or ", kMaxPixels,
                           " in all; lower --sheet-tile or render fewer frames"));
    checkFolderFor(cat("--contact-sheet ", a.contactSheet), a.contactSheet);
  }
  return out;
}

// Every check that can be made before rendering has passed: the output folders are made now, so
// that a run refused earlier leaves nothing behind.
void startOutputs(const RenderArgs& a, const FrameRange& frames, double fps, Outputs& out) {
  createFolderFor(cat("-o ", out.pattern.text()), out.pattern.path(frames.first));
  if (out.video) createFolderFor(cat("--mp4 ", a.mp4), a.mp4);
  if (!a.contactSheet.empty()) createFolderFor(cat("--contact-sheet ", a.contactSheet), a.contactSheet);
  if (!a.contactSheet.empty()) out.sheet.emplace(a.width, a.height, int(frames.count()), a.sheetColumns, a.sheetTile);
  if (out.video) out.video->start(a.width, a.height, fps);
}

// Direct lights (suns, small disks) are lit per pixel with shadow maps: at most
// kMaxDirectLights per frame. The set of lights is the same in every frame (their types and
// radii decide), so the first frame tells.
void checkDirectLights(const RenderArgs& a, const RigLighting& first) {
  if (first.direct.size() > size_t(render::kMaxDirectLights))
    throw Error(cat(a.light.rig.empty() ? std::string("the lights") : a.light.rig, ": ", first.direct.size(),
                    " direct lights (suns and disks up to ", kMaxDirectRadiusDegrees, " deg), at most ",
                    render::kMaxDirectLights, " are lit per pixel; use --no-direct-lights to light them through SH"));
}

// The costs of the frames, ms, summed over them (prepare: once).
struct RenderTimes {
  double prepare = 0.0, light = 0.0, draw = 0.0, readback = 0.0;
  std::vector<LocalLight> local;  // the first frame's lights inside the scene, for the summary
};

// The writer's job for frame f: its EXR, PNG, contact-sheet tile and video frame.
std::function<void()> writeJob(const RenderArgs& a, Outputs& out, int64_t f, std::shared_ptr<const ImageRgb> image,
                               double lightMs, const render::FrameStats& stats) {
  return [&a, &out, f, image, lightMs, stats] {
    auto t1 = std::chrono::steady_clock::now();
    const std::string path = out.pattern.path(f);
    writeExr(path, *image, a.exrCompression);
    if (a.png) writePng(std::filesystem::path(path).replace_extension(".png").string(), *image, float(a.exposure));
    if (out.sheet) out.sheet->add(*image);
    const double frameWriteMs = msSince(t1);
    auto t2 = std::chrono::steady_clock::now();
    if (out.video) out.video->addFrame(*image, float(a.exposure));
    out.encodeMs += msSince(t2);
    out.writeMs += frameWriteMs;
    if (!a.quiet)
      std::fprintf(stderr, "frame %lld -> %s: light %.3f ms, draw %.1f ms, readback %.1f ms, write %.1f ms\n",
                   static_cast<long long>(f), path.c_str(), lightMs, stats.drawMs, stats.readbackMs, frameWriteMs);
  };
}

// Frame f's frame: the camera, the light of the frame (the gathered vertex light valid until
// the next frame's), the options' shadows, lookup and samples, the background if asked for.
render::Frame renderFrame(const RenderArgs& a, const RenderSize& size, const render::CameraView& camera,
                          bake::FrameLight& light, double time, const RigBackground* background,
                          const RigBackground* environment, bool localPerPixel) {
  render::Frame frame;
  frame.camera = camera;
  const bake::DirectIrradiance* v = light.vertexLight;
  frame.setLight(std::move(light.rig), v ? &v->front : nullptr, v ? &v->back : nullptr);
  if (localPerPixel)
    for (const LocalLight& l : light.local)
      if (bake::localLightPerPixel(l)) frame.local.push_back(l);
  if (frame.local.size() > size_t(render::kMaxLocalLights))
    throw Error(cat(a.baked, ": ", frame.local.size(), " point, spot and area lights inside the scene, at most ",
                    render::kMaxLocalLights, " are lit per pixel"));
  frame.shadows.mapSize = a.shadowMapSize;
  frame.time = time;
  frame.probeLookup = a.probeLookup;
  frame.samples = a.msaa;
  frame.background = background;
  frame.materials = a.materials;
  frame.screenReflections = !a.noScreenReflections;
  frame.environment = environment;
  frame.width = int(size.width);
  frame.height = int(size.height);
  return frame;
}

// Renders the frames; frame f is written on the writer's thread while frame f + 1 renders (two
// frames queued at most). Warnings the renderer finds while rendering (direct lights an older
// bake cannot split) are printed once each.
// The receivers' share of the bake's operator: its probe rows for the grid, and their light of the
// last light change (docs/lights.md, "Probes through the operator").
struct ProbeBounce {
  const BounceOperator* op = nullptr;  // null: the grid's receivers get the SH part alone
  const ProbeGrid* grid = nullptr;
  std::vector<glm::vec3> values;
  // The frame's bounce at the probes, recomputed when the frame's light was.
  const std::vector<glm::vec3>* at(const bake::FrameLight& light) {
    if (!op || !light.operatorValues) return nullptr;
    if (light.updated || values.empty()) {
      values.assign(grid->probeCount() * size_t(grid->coeffs()), glm::vec3(0.0f));
      bake::addProbeBounce(*op, *grid, *light.operatorValues, values);
    }
    return &values;
  }
};

// The operator's probe rows where the baked scene has them for this grid (a grid of another bake
// is refused); a warning where its operator has none.
ProbeBounce probeBounce(const RenderArgs& a, const Scene& scene, const ProbeGrid& grid,
                        std::vector<std::string>& warnings) {
  ProbeBounce b;
  if (a.probes.empty() || !scene.bounceOperator || a.gather.noOperator) return b;
  if (!scene.bounceOperator->probeRows.present()) {
    warnings.push_back(cat(a.baked,
                           " has no probe rows in its bounce operator (baked without --probes, or by an older prt): "
                           "the receivers get only the bounced light the probes' SH carries"));
    return b;
  }
  bake::checkProbeRows(*scene.bounceOperator, grid, cat(a.baked, " (with ", a.probes, ")"));
  b.op = scene.bounceOperator.get();
  b.grid = &grid;
  return b;
}

RenderTimes renderFrames(const RenderArgs& a, const FrameLights& lights, const RenderSize& size, double fps,
                         const render::CameraView& camera, render::Renderer& renderer, bake::FrameLighting& lighting,
                         ProbeBounce& probeBounce, Outputs& out) {
  RenderTimes t;
  size_t warningsShown = renderer.warnings().size();
  FrameWriter writer(2);
  for (int64_t f = lights.frames.first; f <= lights.frames.last; ++f) {
    bake::FrameLight light = lighting.at(double(f));
    if (f == lights.frames.first) t.local = light.local;
    RigBackground background;
    if (a.background == Background::Sky) background = lights.rig.background(double(f));
    // The light glossy surfaces reflect besides the direct lights: the rig's SH part.
    RigBackground environment;
    const bool full = a.materials == render::MaterialShading::Full;
    if (full) environment = lights.rig.shRadiance(double(f));
    render::Frame frame =
        renderFrame(a, size, camera, light, double(f) / fps, a.background == Background::Sky ? &background : nullptr,
                    full ? &environment : nullptr, lights.localPerPixel);
    const auto tProbes = std::chrono::steady_clock::now();
    frame.probeBounce = probeBounce.at(light);
    const double probesMs = msSince(tProbes);
    auto image = std::make_shared<const ImageRgb>(
        a.supersample > 1 ? downsampleBox(renderer.render(frame), a.supersample) : renderer.render(frame));
    const std::vector<std::string> now = renderer.warnings();
    for (; warningsShown < now.size(); ++warningsShown)
      if (!a.quiet) std::fprintf(stderr, "prt: warning: %s\n", now[warningsShown].c_str());
    // The light update: the rig's SH, the gathered vertex light when the lights changed, and,
    // with probes, relighting and uploading the grid.
    const render::FrameStats stats = renderer.lastFrame();
    const double frameLightMs = light.seconds * 1e3 + probesMs + stats.lightMs;
    t.light += frameLightMs;
    t.draw += stats.drawMs;
    t.readback += stats.readbackMs;
    writer.push(writeJob(a, out, f, image, frameLightMs, stats));
  }
  writer.finish();
  return t;
}

// The summary's first paragraph: the frames, the camera, the costs.
void printFrames(const RenderArgs& a, const FrameLights& lights, const RenderSize& size, const Outputs& out,
                 const RenderTimes& t, const std::string& device, const ChosenCamera& camera,
                 const render::FrameStats& last, int bands) {
  const int64_t n = lights.frames.count();
  const double perFrame = 1.0 / double(n);
  std::fprintf(
      stderr,
      "prt render: %lld frame%s %dx%d written (%s .. %s)%s on %s\n"
      "  camera: %s\n"
      "  %.2f ms/frame draw + %.2f ms/frame readback, %.3f ms per light update (%zu lights, %d bands, "
      "window %s; maps projected once in %.1f ms), %.2f ms/frame writing; background %s, %d sample%s per pixel%s\n",
      static_cast<long long>(n), n == 1 ? "" : "s", a.width, a.height, out.pattern.path(lights.frames.first).c_str(),
      out.pattern.path(lights.frames.last).c_str(), a.png ? " + PNG" : "", device.c_str(), camera.description.c_str(),
      t.draw * perFrame, t.readback * perFrame, t.light * perFrame, lights.rig.lights.size(), bands,
      sh::windowName(lights.rig.window), t.prepare, out.writeMs * perFrame,
      a.background == Background::Sky ? "sky" : "black", last.samples, last.samples == 1 ? "" : "s",
      a.supersample > 1 ? cat(", supersampled ", a.supersample, "x", a.supersample, " (rendered ", size.width, "x",
                              size.height, ", averaged down)")
                              .c_str()
                        : "");
}

// The summary's lines on the lights inside the scene (the first frame's).
void printLocalLights(const std::vector<LocalLight>& local, const render::FrameStats& last) {
  if (local.empty()) return;
  const size_t pixel = last.localLights;
  const std::string how =
      pixel ? cat(pixel, " per pixel with cube shadow maps (", last.localShadowMaps, " faces of ", last.localMapSize,
                  "x", last.localMapSize, ")", pixel < local.size() ? ", the rest at the baked vertices" : "")
            : std::string("at the baked vertices");
  std::fprintf(stderr, "  lights inside the scene: %zu (%s; their bounces at the baked vertices):\n", local.size(),
               how.c_str());
  for (const LocalLight& l : local) std::fprintf(stderr, "    %s\n", describeLocalLight(l).c_str());
}

// How the lights' bounces were lit, for the summary: through the operator or gathered, and the
// cost of each frame that redid them (its shadow rays and its products or gather).
std::string bounceText(const RenderArgs& a, const bake::FrameLighting& lighting, const render::FrameStats& last) {
  const bake::FrameLightingStats& st = lighting.stats();
  const double updates = std::max(st.updates, 1);
  const char* receivers = last.directReceivers ? ", on receivers through the probes" : "";
  char text[256];
  if (lighting.usesOperator())
    std::snprintf(text, sizeof text,
                  "on baked surfaces through the bake's bounce operator, redone for %d of the frames (%.2f ms each: "
                  "shadow rays %.2f, products %.2f)%s",
                  st.updates, 1e3 * st.updateSeconds / updates, 1e3 * st.shadowSeconds / updates,
                  1e3 * st.gatherSeconds / updates, receivers);
  else if (lighting.gathers())
    std::snprintf(text, sizeof text,
                  "on baked surfaces gathered with %d rays per vertex (traced once in %.2f s), redone for %d of the "
                  "frames (%.1f ms each: shadow rays %.1f, gather %.1f)%s",
                  a.gather.bounceSamples, st.traceSeconds, st.updates, 1e3 * st.updateSeconds / updates,
                  1e3 * st.shadowSeconds / updates, 1e3 * st.gatherSeconds / updates, receivers);
  else
    return "through the transfer";
  return text;
}

// The summary's lines on the direct lights, their bounces and the sky detail.
void printLighting(const RenderArgs& a, const FrameLights& lights, const RigLighting& first,
                   const bake::FrameLighting& lighting, const render::FrameStats& last, int bands,
                   const std::vector<LocalLight>& local) {
  const bake::FrameLightingStats& st = lighting.stats();
  const double updates = std::max(st.updates, 1);
  if (!first.direct.empty()) {
    const std::string bounces = bounceText(a, lighting, last);
    const std::string how =
        last.directBaked || last.directReceivers
            ? cat("per pixel, exactly, with PCSS shadow maps of ", last.shadowMapSize, "x", last.shadowMapSize, ", ",
                  last.cascades, " cascade", last.cascades == 1 ? "" : "s", " per light, ",
                  last.directBaked ? "on baked surfaces" : "", last.directBaked && last.directReceivers ? " and " : "",
                  last.directReceivers ? "on receivers" : "", "; their bounces ", bounces)
            : std::string("through SH (no direct part in the bake)");
    std::fprintf(stderr, "  direct lights (frame %lld; %s):\n", static_cast<long long>(lights.frames.first),
                 how.c_str());
    for (const std::string& line : describeDirectLights(first, lights.rig))
      std::fprintf(stderr, "    %s\n", line.c_str());
  } else if (a.light.noDirect) {
    std::fprintf(stderr, "  direct lights: none apart (--no-direct-lights: every light through the SH transfer)\n");
  }
  printLocalLights(local, last);
  if (first.direct.empty() && !local.empty() && lighting.gathers())
    std::fprintf(stderr, "  their bounces %s\n", bounceText(a, lighting, last).c_str());
  if (lighting.skyDetail() && lighting.usesOperator())
    std::fprintf(
        stderr,
        "  sky detail: the sky's light beyond %d bands on baked surfaces, through the bake's bounce operator%s "
        "(docs/lights.md, \"Sky detail\"), redone for %d of the frames\n",
        bands, first.direct.empty() ? "" : " with the bounces", st.updates);
  else if (lighting.skyDetail())
    std::fprintf(stderr,
                 "  sky detail: the sky's light beyond %d bands on baked surfaces, gathered over the same %d rays per "
                 "vertex%s (docs/lights.md, \"Sky detail\"), redone for %d of the frames (%.1f ms each)\n",
                 bands, a.gather.bounceSamples, first.direct.empty() ? "" : " as the bounces", st.updates,
                 1e3 * st.updateSeconds / updates);
}

// The summary's last lines: the video, the contact sheet, the total.
void printOutputs(const RenderArgs& a, const Outputs& out, int64_t n, double fps, double totalMs) {
  const double perFrame = 1.0 / double(n);
  if (out.video)
    std::fprintf(stderr, "  video %s: %lld frames at %g fps, %.2f ms/frame encoding (%s)\n", a.mp4.c_str(),
                 static_cast<long long>(n), fps, out.encodeMs * perFrame, out.video->ffmpeg().c_str());
  if (out.sheet)
    std::fprintf(stderr, "  contact sheet %s: %d columns of %dx%d tiles (1/%d)\n", a.contactSheet.c_str(),
                 out.sheet->columns(), out.sheet->tileWidth(), out.sheet->tileHeight(), out.sheet->factor());
  std::fprintf(stderr, "  total %.2f s (%.1f ms/frame)\n", totalMs / 1000.0, totalMs * perFrame);
}

}  // namespace

namespace {

void addMaterialOption(CLI::App& r, RenderArgs& a) {
  r.add_option("--materials", a.materials,
               "full: the glTF metallic-roughness material per pixel (metals, gloss, normal, occlusion and emissive "
               "maps, highlights of the direct lights and of the environment); diffuse: every surface Lambertian "
               "with its base colour, as prt relight (docs/render.md, \"Materials\")")
      ->transform(choice<render::MaterialShading>(
          {{"full", render::MaterialShading::Full}, {"diffuse", render::MaterialShading::Diffuse}}))
      ->default_str("full");
  r.add_flag("--no-screen-reflections", a.noScreenReflections,
             "With --materials full: glossy surfaces reflect the environment and the surroundings' mean radiance "
             "only; by default (without --msaa) they reflect the surface their mirror direction meets on the screen, "
             "found through the depth buffer, where there is one (docs/render.md, \"Materials\")");
}

void addSceneLightsOption(CLI::App& r, RenderArgs& a) {
  r.add_flag("--no-scene-lights", a.noSceneLights,
             "Leave the scene's own lights (KHR_lights_punctual point, spot and directional lights, emissive "
             "surfaces) dark; by default they light it, and no other light is needed (docs/lights.md, \"Lights "
             "inside the scene\")");
}

}  // namespace

void addRender(CLI::App& r, RenderArgs& a) {
  r.add_option("baked", a.baked, "Baked scene (.glb from prt bake)")->required();
  r.add_option("-o,--output", a.output,
               "Frame path (.exr) with a frame field %d or %0Nd, e.g. out/frame_%04d.exr (a plain name for one "
               "frame); its folder is created")
      ->capture_default_str();
  r.add_option_function<std::string>(
       "--frames", [&a](const std::string& v) { a.frames = parseFrames(v); },
       "Frame range A-B (inclusive) or A; default 0-0, or the --rig's keyframe range (up to 100000 frames)")
      ->default_str("0-0");
  r.add_option_function<std::string>(
       "--size", [&a](const std::string& v) { std::tie(a.width, a.height) = parseSize(v); },
       "Image size WxH (each 1..16384, at most 8192x8192 pixels)")
      ->default_str(cat(a.width, "x", a.height));
  addCameraOptions(r, a);
  r.add_option("--gl", a.gl, "OpenGL back end")
      ->transform(choice<render::GlBackend>({{"osmesa", render::GlBackend::OSMesa}, {"egl", render::GlBackend::Egl}}))
      ->default_str("osmesa");
  addLightOptions(r, a.light, /*animated=*/true);
  r.add_option("--exr-compression", a.exrCompression, "EXR compression, all lossless (none is the fastest)")
      ->transform(choice<ExrCompression>(
          {{"zip", ExrCompression::Zip}, {"piz", ExrCompression::Piz}, {"none", ExrCompression::None}}))
      ->default_str("zip");
  r.add_flag("--png", a.png, "Also write tone-mapped sRGB PNGs next to the EXRs");
  r.add_option("--exposure", a.exposure, "Exposure in stops for PNG, MP4 and contact sheet")
      ->check(finite())
      ->capture_default_str();
  r.add_option("--mp4", a.mp4, "Also encode the frames as H.264 MP4 with ffmpeg (must be on PATH)");
  r.add_option_function<double>(
       "--fps", [&a](const double& v) { a.fps = v; },
       "Frames per second: frame f shows the scene's animations at time f/fps; also the --mp4 rate "
       "(default: the rig's fps, else 24)")
      ->check(finitePositive());
  r.add_option("--probes", a.probes, "Probe grid (.vdb from prt bake --probes) lighting the receivers");
  r.add_option("--probe-lookup", a.probeLookup,
               "Where receivers interpolate the probe grid: pixel (exact) or vertex (faster, exact only where "
               "the probe field is linear over each triangle)")
      ->transform(choice<render::ProbeLookup>(
          {{"pixel", render::ProbeLookup::PerPixel}, {"vertex", render::ProbeLookup::PerVertex}}))
      ->default_str("pixel");
  r.add_option("--background", a.background,
               "What pixels without geometry show: black, or sky (the rig's maps, suns and disks as seen along "
               "each pixel's ray)")
      ->transform(choice<Background>({{"black", Background::Black}, {"sky", Background::Sky}}))
      ->default_str("black");
  r.add_option("--msaa", a.msaa,
               "Anti-aliasing: samples per pixel, 1 (off), 2, 4 ... up to the GL's limit (4 on llvmpipe); each "
               "pixel is the mean of its samples")
      ->check(CLI::Validator(
          [](std::string& v) {
            int n = 0;
            const bool ok = CLI::detail::lexical_cast(v, n) && n >= 1 && (n & (n - 1)) == 0;
            return ok ? std::string() : cat(v, " is not a power of two: 1, 2, 4, 8 ...");
          },
          "power of two"))
      ->capture_default_str();
  r.add_option("--supersample", a.supersample,
               "Renders N x N pixels for each output pixel and writes their mean (a box filter): anti-aliases "
               "shading too (shadow edges, the sun's patches), which --msaa does not; costs about N^2")
      ->check(CLI::Range(1, 8))
      ->capture_default_str();
  r.add_option("--shadow-map-size", a.shadowMapSize,
               "Texels a side of each direct light's shadow map (per cascade); suns and disks up to 20 deg are lit "
               "per pixel with PCSS-filtered shadow maps (docs/render.md)")
      ->check(CLI::Range(16, 8192))
      ->capture_default_str();
  addMaterialOption(r, a);
  addGatherOptions(r, a.gather);
  r.add_option("--contact-sheet", a.contactSheet, "Also write a PNG grid of all frames, downscaled");
  r.add_option("--sheet-columns", a.sheetColumns, "Contact sheet columns (0 = about square)")
      ->check(CLI::Range(0, std::numeric_limits<int>::max()).description(">= 0"))
      ->capture_default_str();
  r.add_option("--sheet-tile", a.sheetTile, "Contact sheet: largest tile side in pixels")
      ->check(CLI::Range(1, std::numeric_limits<int>::max()).description(">= 1"))
      ->capture_default_str();
  addSceneLightsOption(r, a);
  r.add_flag("-q,--quiet", a.quiet, "No per-frame lines, no summary");
}

int runRender(const RenderArgs& a) {
  const auto tStart = std::chrono::steady_clock::now();
  const RenderSize size = renderSize(a);
  LoadOptions load;
  // Normal, occlusion, emissive; the emissive textures also for the emissive surfaces as lights.
  load.shadingTextures = a.materials == render::MaterialShading::Full || !a.noSceneLights;
  Scene scene = loadScene(a.baked, load);
  if (scene.transferBands == 0) throw Error(cat(a.baked, ": holds no baked transfer (run prt bake first)"));
  const bool ownLights = !scene.lights.empty() || !bake::emissiveLightsOf(scene).empty();
  FrameLights lights = frameLights(a, !a.noSceneLights && ownLights);
  Outputs out = checkOutputs(a, lights.frames);
  const double fps = a.fps ? *a.fps : lights.rig.fps.value_or(kDefaultFps);

  const int bands = scene.transferBands;
  const ChosenCamera camera = chooseCamera(a, orbitCamera(a), scene, double(a.width) / a.height);
  ProbeGrid probes;
  std::vector<std::string> warnings = scene.warnings;  // as every command that reads a scene prints them
  if (!a.probes.empty()) {
    probes = readProbeGrid(a.probes);
    for (const std::string& w : checkProbesMatch(probes, scene, a)) warnings.push_back(w);
  }
  ProbeBounce bounceAtProbes = probeBounce(a, scene, probes, warnings);
  render::GlContext context(a.gl, int(size.width), int(size.height));
  if (a.msaa > context.maxSamples())
    throw Error(cat("--msaa ", a.msaa, ": ", context.renderer(), " allows at most ", context.maxSamples(), " samples"));
  render::Renderer renderer(context, scene);
  if (!a.probes.empty()) renderer.setProbes(probes);
  for (const std::string& w : renderer.warnings()) warnings.push_back(w);
  const RigLighting first = lightingAt(lights.rig, a.light, double(lights.frames.first), bands);
  checkDirectLights(a, first);
  if (!a.quiet)
    for (const std::string& w : warnings) std::fprintf(stderr, "prt: warning: %s\n", w.c_str());
  startOutputs(a, lights.frames, fps, out);

  // Maps are projected once, here; a frame then costs a rotation and the analytic lights. The
  // direct lights' bounces on baked surfaces, from their shadowed light at the vertices, and the
  // sky's detail beyond the band limit (it bounces with them) are gathered over the bake's own
  // rays (docs/lights.md, "Sky detail"), redone only when the direct lights or the sky change.
  const auto tPrepare = std::chrono::steady_clock::now();
  lights.rig.prepare(bands);
  const double prepareMs = msSince(tPrepare);
  bake::FrameLightingSettings gather = frameLightingSettings(a.light, a.gather);
  gather.shadowSamples = kBounceShadowSamples;
  gather.sceneLights = !a.noSceneLights;
  // Point, spot and area lights per pixel where the baked instances are (the direct part of the
  // transfer), their shadowed light at the vertices only for the bounces; emissive surfaces at
  // the vertices, with as many shadow rays as prt relight's.
  gather.localPerPixel = lights.localPerPixel = hasDirectTransfer(scene);
  gather.localShadowSamples = kLocalShadowSamples;
  bake::FrameLighting lighting(scene, lights.rig, gather);
  RenderTimes times = renderFrames(a, lights, size, fps, camera.view, renderer, lighting, bounceAtProbes, out);
  times.prepare = prepareMs;
  auto tEnd = std::chrono::steady_clock::now();
  if (out.video) out.video->finish();
  out.encodeMs += msSince(tEnd);
  if (out.sheet) out.sheet->write(a.contactSheet, float(a.exposure));
  if (a.quiet) return 0;
  printFrames(a, lights, size, out, times, context.description(), camera, renderer.lastFrame(), bands);
  printLighting(a, lights, first, lighting, renderer.lastFrame(), bands, times.local);
  printOutputs(a, out, lights.frames.count(), fps, msSince(tStart));
  return 0;
}

}  // namespace prt::tools
