// `prt render`: relit frames of a baked scene, headless (OSMesa or EGL).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "light_options.h"
#include "prt/image.h"
#include "prt/render/gl_context.h"
#include "prt/render/renderer.h"

namespace prt::tools {

/// Frames A..B, inclusive.
struct FrameRange {
  int64_t first = 0, last = 0;
  int64_t count() const { return last - first + 1; }
};

/// What pixels without geometry show.
enum class Background { Black, Sky };

struct RenderArgs {
  std::string baked, output = "out/frame_%04d.exr", camera;
  std::optional<FrameRange> frames;  // none: 0-0, or the --rig's keyframe range
  int width = 640, height = 360;
  render::GlBackend gl = render::GlBackend::OSMesa;
  LightOptions light;
  bool png = false;
  double exposure = 0.0;
  std::optional<double> fps;  // none: the rig's fps, else 24; frame f is at time f / fps of the animations
  std::string probes;         // probe grid (.vdb) lighting the receivers
  ExrCompression exrCompression = ExrCompression::Zip;
  render::ProbeLookup probeLookup = render::ProbeLookup::PerPixel;  // where receivers interpolate the grid
  Background background = Background::Black;
  int msaa = 1;              // samples per pixel
  int supersample = 1;       // rendered supersample x supersample pixels per output pixel, averaged down
  int shadowMapSize = 1024;  // texels a side of each direct light's shadow map (and cascade)
  render::MaterialShading materials = render::MaterialShading::Full;  // the glTF material, or diffuse only
  bool noScreenReflections = false;  // Frame::screenReflections off
  GatherOptions gather;  // the bake's rays gathering the direct lights' bounces and the sky detail
  std::string mp4, contactSheet;
  int sheetColumns = 0, sheetTile = 192;
  double orbitAzimuth = 0.0, orbitElevation = 20.0, orbitFov = 45.0, orbitDistance = 0.0;  // distance 0: fit
  std::vector<double> orbitTarget;  // empty: the centre of the scene bounds
  std::string orbitOption;          // the first --orbit-* option given: it selects the orbit camera
  bool noSceneLights = false;       // --no-scene-lights: the file's own lights and emissive surfaces left dark
  bool quiet = false;
};

/// Adds the options of `prt render` to its subcommand.
void addRender(CLI::App& cmd, RenderArgs& a);
/// Renders. Throws prt::Error on bad input, UsageError on options that do not go together.
int runRender(const RenderArgs& a);

}  // namespace prt::tools
