// The sky as the sky detail reads it (docs/lights.md, "Sky detail"): each map averaged down to
// pixels of about four gather rays' share of the hemisphere, kept per map image across frames.
// Shared by the gather at relight time (direct_bounce.cpp) and the bounce operator's sky bins
// (operator/evaluate.cpp).
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <utility>

#include "prt/image.h"
#include "prt/light_rig.h"

namespace prt::bake {

/// The map averaged down by a whole factor that divides both sides, to an equirectangular
/// width of about √(2πK)/2 (two of K rays across a pixel), each output pixel the solid-angle
/// weighted mean of its block; the map itself where no factor above 1 fits.
std::shared_ptr<const ImageRgb> prefilteredSky(const std::shared_ptr<const ImageRgb>& map, uint32_t K);

/// `sky` with its maps prefiltered for K rays, each image filtered once and kept while the
/// following calls still use it (a rig's maps are the same images every frame, only turned).
class PrefilteredSky {
 public:
  explicit PrefilteredSky(uint32_t K) : K_(K) {}
  RigBackground operator()(const RigBackground& sky) const;

 private:
  uint32_t K_;
  mutable std::mutex mutex_;
  mutable std::map<const ImageRgb*, std::pair<std::shared_ptr<const ImageRgb>, std::shared_ptr<const ImageRgb>>> kept_;
};

}  // namespace prt::bake
