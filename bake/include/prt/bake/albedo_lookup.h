// Base colour at ray hits, with a fast path for instances of uniform colour and a batched one,
// eight hits at a time with AVX-512, for textured and vertex-coloured instances.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "prt/bake/surface_layout.h"
#include "prt/scene.h"

namespace prt::bake {

struct AlbedoLookup {
  const Scene& scene;
  std::vector<uint8_t> uniform;     // per instance: no texture, no vertex colours
  std::vector<glm::vec3> constant;  // its colour when uniform
  bool varies = false;              // some instance is not uniform

  explicit AlbedoLookup(const Scene& s);

  glm::vec3 at(uint32_t mesh, uint32_t localTri, float b1, float b2) const {
    if (uniform[mesh]) return constant[mesh];
    return albedoAt(scene, scene.meshes[mesh], localTri, b1, b2);
  }

  /// out[k] = at(mesh[k], tri[k], b1[k], b2[k]) for k < n, bit for bit. With
  /// AVX-512 (prt/bake/kernels.h) eight hits at a time: the corners, texture coordinates, texels,
  /// their decode and vertex colours by gathers, and Texture::sample's wrap and bilinear filter
  /// in doubles, each operation rounded as the scalar code rounds it. A hit on an instance the
  /// kernel does not take (a texture without 8-bit texels) is looked up one by one.
  void atMany(const uint32_t* mesh, const uint32_t* tri, const float* b1, const float* b2, uint32_t n,
              glm::vec3* out) const;

  /// What atMany's kernel reads of an instance: one cache line, gathered by instance.
  struct alignas(64) Batched {
    const uint32_t* indices = nullptr;     // 3 per triangle
    const glm::vec2* texcoords = nullptr;  // where the base colour is sampled (kTextured)
    const uint32_t* texels8 = nullptr;     // Texture::texels8
    const glm::vec4* colors = nullptr;     // COLOR_0 (kColoured)
    float factor[3] = {1.0f, 1.0f, 1.0f};  // baseColorFactor's RGB (1 without a material)
    int32_t width = 0, height = 0;
    int32_t levels = 0;  // the texture's colour decode: levels_[levels .. +256)
    uint32_t flags = 0;  // kKernel | kTextured | kColoured | wrap kinds << 8, << 10
  };
  static constexpr uint32_t kKernel = 1, kTextured = 2, kColoured = 4;
  /// atMany's kernels (prt/bake/kernels.h): a kernel over the tables, null where there is none.
  struct ManyKernels {
    void (*many)(const AlbedoLookup& lookup, const Batched* table, const float* levels, const uint32_t* mesh,
                 const uint32_t* tri, const float* b1, const float* b2, uint32_t n, glm::vec3* out);
  };

 private:
  std::vector<Batched> batched_;  // per instance
  std::vector<float> levels_;     // 256 per texture: Texture::levels8[0]
  // The kernel of the set in use when constructed, where some instance is batched and instance
  // offsets fit in 32 bits; else null (at() hit by hit).
  decltype(ManyKernels::many) many_ = nullptr;
};

// The base colours of one vertex's hit records on instances whose colour varies over their
// surface (textured or vertex-coloured), in the records' order: start() on the vertex's records,
// then next() for each such record. They are looked up kWindow at a time (AlbedoLookup::atMany:
// eight at a time with AVX-512), the barycentrics dequantised as the gathers do. A thread's
// scratch, kept from vertex to vertex (kWindow · 32 bytes, whatever the sample count).
class VaryingColours {
 public:
  static constexpr uint32_t kWindow = 4096;
  void start(const AlbedoLookup& albedo, const Layout& lay, const HitRecord* hits, uint32_t first, uint32_t last) {
    albedo_ = &albedo, lay_ = &lay, hits_ = hits, scan_ = first, last_ = last, at_ = count_ = 0;
  }
  const glm::vec3& next() {
    if (at_ == count_) fill();
    return rgb_[at_++];
  }

 private:
  void fill() {
    if (mesh_.empty()) {
      for (auto* v : {&mesh_, &tri_}) v->resize(kWindow);
      for (auto* v : {&b1_, &b2_}) v->resize(kWindow);
      rgb_.resize(kWindow);
    }
    at_ = count_ = 0;
    for (; scan_ < last_ && count_ < kWindow; ++scan_) {
      const HitRecord& rec = hits_[scan_];
      const uint32_t m = lay_->meshOfTri[rec.tri];
      if (albedo_->uniform[m]) continue;
      mesh_[count_] = m, tri_[count_] = lay_->localTriangle(rec.tri);
      b1_[count_] = rec.b1 * (1.0f / 65535.0f), b2_[count_] = rec.b2 * (1.0f / 65535.0f);
      ++count_;
    }
    albedo_->atMany(mesh_.data(), tri_.data(), b1_.data(), b2_.data(), count_, rgb_.data());
  }
  const AlbedoLookup* albedo_ = nullptr;
  const Layout* lay_ = nullptr;
  const HitRecord* hits_ = nullptr;
  uint32_t scan_ = 0, last_ = 0, at_ = 0, count_ = 0;
  std::vector<uint32_t> mesh_, tri_;
  std::vector<float> b1_, b2_;
  std::vector<glm::vec3> rgb_;
};

}  // namespace prt::bake
