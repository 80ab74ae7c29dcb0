// Base colour at ray hits, with a fast path for instances of uniform colour and a batched one,
// eight hits at a time with AVX-512, for textured and vertex-coloured instances.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "prt/scene.h"

namespace prt::bake {

struct AlbedoLookup {
  const Scene& scene;
  std::vector<uint8_t> uniform;      // per instance: no texture, no vertex colours
  std::vector<glm::vec3> constant;   // its colour when uniform
  bool varies = false;               // some instance is not uniform

  explicit AlbedoLookup(const Scene& s);

  glm::vec3 at(uint32_t mesh, uint32_t localTri, float b1, float b2) const {
    if (uniform[mesh]) return constant[mesh];
    return albedoAt(scene, scene.meshes[mesh], localTri, b1, b2);
  }

  /// out[k] = at(mesh[k], tri[k], b1[k], b2[k]) for k < n, bit for bit. With
  /// AVX-512 (useAvx512Kernels) eight hits at a time: the corners, texture coordinates, texels,
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
    int32_t levels = 0;                    // the texture's colour decode: levels_[levels .. +256)
    uint32_t flags = 0;                    // kKernel | kTextured | kColoured | wrap kinds << 8, << 10
  };
  static constexpr uint32_t kKernel = 1, kTextured = 2, kColoured = 4;

private:
  std::vector<Batched> batched_;  // per instance
  std::vector<float> levels_;     // 256 per texture: Texture::levels8[0]
  bool kernel_ = false;           // some instance is batched, and instance offsets fit in 32 bits
};

}  // namespace prt::bake
