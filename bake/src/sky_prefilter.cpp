// The sky as the sky detail reads it (sky_prefilter.h).
#include "sky_prefilter.h"

#include <algorithm>
#include <cmath>

#include "prt/light.h"
#include "prt/math.h"

namespace prt::bake {

// The map averaged down to pixels of about four rays' share of the hemisphere each (2π/K
// per ray; two rays across a pixel: an equirectangular width of √(2πK)/2, 20 pixels at K = 256,
// so a 1k map is read at 32 × 16), by a whole factor that divides both sides, each output pixel
// the solid-angle weighted mean of its block: the power is kept, and a bright feature smaller
// than that (a lamp the sources split off left behind, a sun's glow) is spread over it instead
// of being hit by one ray in a hundred vertices (the detail's noise). The bilinear reading then
// filters over about two such pixels. Measured on the validation room (docs/validation.md):
// one ray a pixel was noisier (Royal Esplanade 3.3% / 11.9% per vertex), four rays across
// blurrier (3.4% / 13.7%, Venice Sunset 1.8% / 5.1%), two across the best (2.9% / 10.5%,
// 0.9% / 3.0%).
std::shared_ptr<const ImageRgb> prefilteredSky(const std::shared_ptr<const ImageRgb>& map, uint32_t K) {
  const int w = map->width, h = map->height;
  const double target = 0.5 * std::sqrt(2.0 * kPiF * double(K));
  int f = std::max(1, int(std::floor(double(w) / target)));
  while (f > 1 && (w % f != 0 || h % f != 0)) --f;
  if (f == 1) return map;
  auto out = std::make_shared<ImageRgb>(w / f, h / f);
  for (int Y = 0; Y < out->height; ++Y)
    for (int X = 0; X < out->width; ++X) {
      glm::dvec3 sum(0.0);
      double weight = 0.0;
      for (int y = Y * f; y < (Y + 1) * f; ++y) {
        const double omega = equirectPixelSolidAngle(y, w, h);
        for (int x = X * f; x < (X + 1) * f; ++x) sum += omega * glm::dvec3(map->at(x, y));
        weight += omega * f;
      }
      out->at(X, Y) = glm::vec3(sum / weight);
    }
  return out;
}

RigBackground PrefilteredSky::operator()(const RigBackground& skyIn) const {
  RigBackground sky = skyIn;
  // Only this call's images are kept, so a rig whose maps change every frame does not
  // accumulate them. An entry keeps its source image alive, so its address is not reused.
  std::lock_guard<std::mutex> lock(mutex_);
  decltype(kept_) kept;
  for (RigBackground::Map& m : sky.maps) {
    auto& [source, f] = kept[m.image.get()];
    if (!f) {
      if (auto it = kept_.find(m.image.get()); it != kept_.end())
        std::tie(source, f) = it->second;
      else
        source = m.image, f = prefilteredSky(m.image, K_);
    }
    m.image = f;
  }
  kept_ = std::move(kept);
  return sky;
}

}  // namespace prt::bake
