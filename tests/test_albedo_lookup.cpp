// AlbedoLookup::atMany (prt/bake/albedo_lookup.h): the base colour of many hits at once, eight
// at a time with AVX-512, must give albedoAt's bits for every hit: textures of 8-bit texels in
// every wrap mode (sizes down to 1 × 1, coordinates far outside [0, 1], non-finite ones), float
// texels (looked up one by one), vertex colours with and without a texture, factors, instances
// without a material or without coordinates.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "prt/bake/albedo_lookup.h"  // AlbedoLookup, VaryingColours
#include "prt/bake/kernels.h"
#include "prt/bake/surface_layout.h"  // makeLayout, HitRecord
#include "prt/scene.h"

namespace prt {
namespace {

// A texture of w × h random 8-bit texels, decoded by a colour table of its own (increasing, as a
// transfer curve is) and alpha's, or of float texels only.
Texture randomTexture(std::mt19937& rng, int w, int h, int wrapS, int wrapT, bool eightBit, float gamma) {
  Texture t;
  t.width = w, t.height = h, t.wrapS = wrapS, t.wrapT = wrapT;
  for (int i = 0; i < 256; ++i) {
    t.levels8[0][size_t(i)] = std::pow(float(i) / 255.0f, gamma);
    t.levels8[1][size_t(i)] = float(i) / 255.0f;
  }
  std::uniform_int_distribution<uint32_t> bits;
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (int i = 0; i < w * h; ++i) {
    if (eightBit) {
      const uint32_t p = bits(rng);
      t.texels8.push_back(p);
      t.texels.emplace_back(t.levels8[0][p & 255u], t.levels8[0][(p >> 8) & 255u], t.levels8[0][(p >> 16) & 255u],
                            t.levels8[1][p >> 24]);
    } else {
      t.texels.emplace_back(unit(rng), unit(rng), unit(rng), unit(rng));
    }
  }
  return t;
}

// An instance of `triangles` triangles over `vertices` vertices, coordinates mostly in [−3, 4],
// some far out or not finite.
MeshInstance randomMesh(std::mt19937& rng, int material, size_t vertices, size_t triangles, bool texcoords,
                        bool colors) {
  MeshInstance m;
  m.material = material;
  m.positions.assign(vertices, glm::vec3(0.0f));
  std::uniform_real_distribution<float> uv(-3.0f, 4.0f), unit(0.0f, 1.5f);
  std::uniform_int_distribution<uint32_t> vertex(0, uint32_t(vertices - 1)), odd(0, 40);
  for (size_t v = 0; v < vertices && texcoords; ++v) {
    glm::vec2 c(uv(rng), uv(rng));
    switch (odd(rng)) {
      case 0:
        c.x = 1e7f;
        break;
      case 1:
        c.y = -3e9f;
        break;
      case 2:
        c.x = std::numeric_limits<float>::quiet_NaN();
        break;
      case 3:
        c.y = std::numeric_limits<float>::infinity();
        break;
      case 4:
        c = glm::vec2(0.0f, 1.0f);
        break;
      default:
        break;
    }
    m.texcoords.push_back(c);
  }
  for (size_t v = 0; v < vertices && colors; ++v) m.colors.emplace_back(unit(rng), unit(rng), unit(rng), unit(rng));
  for (size_t i = 0; i < 3 * triangles; ++i) m.indices.push_back(vertex(rng));
  return m;
}

// Instances of every kind the lookup tells apart, over the textures above; some double-sided.
Scene randomScene(std::mt19937& rng) {
  Scene s;
  const int R = Texture::kRepeat, C = Texture::kClampToEdge, M = Texture::kMirroredRepeat;
  s.textures.push_back(randomTexture(rng, 7, 5, R, R, true, 2.2f));
  s.textures.push_back(randomTexture(rng, 1, 1, C, M, true, 1.0f));
  s.textures.push_back(randomTexture(rng, 16, 9, M, C, true, 2.4f));
  s.textures.push_back(randomTexture(rng, 4, 4, R, R, false, 1.0f));     // float texels: one by one
  s.textures.push_back(randomTexture(rng, 3, 2, 12345, M, true, 1.8f));  // a mode glTF does not name: REPEAT
  s.textures.push_back(Texture{});                                       // empty: sample() gives 1
  for (int t = 0; t < int(s.textures.size()); ++t) {
    Material m;
    m.baseColorFactor = glm::vec4(0.3f + 0.1f * t, 0.9f, 0.55f, 1.0f);
    m.baseColorTexture = t;
    m.doubleSided = t % 2 == 1;  // both sides baked: back triangles in the bake's numbering
    // Metallic 0.35 on one: the kernel's factor must be albedoAt's first product, (1 − 0.35)·factor.
    m.metallicFactor = t == 1 ? 0.35f : 0.0f;
    s.materials.push_back(m);
  }
  Material plain;
  plain.baseColorFactor = glm::vec4(0.2f, 0.4f, 0.8f, 1.0f);
  plain.metallicFactor = 0.0f;
  s.materials.push_back(plain);
  for (int t = 0; t < int(s.textures.size()); ++t) {
    s.meshes.push_back(randomMesh(rng, t, 40, 60, true, false));
    s.meshes.push_back(randomMesh(rng, t, 30, 50, true, true));  // texture and vertex colours
  }
  s.meshes.push_back(randomMesh(rng, 0, 20, 30, false, false));  // textured material, no coordinates
  s.meshes.push_back(randomMesh(rng, 0, 20, 30, false, true));
  s.meshes.push_back(randomMesh(rng, -1, 20, 30, false, true));                       // no material: colours alone
  s.meshes.push_back(randomMesh(rng, int(s.textures.size()), 20, 30, true, true));    // factor × colours
  s.meshes.push_back(randomMesh(rng, int(s.textures.size()), 20, 30, false, false));  // uniform
  return s;
}

TEST(AlbedoLookup, ManyAtOnceGiveAtsBits) {
  if (bake::activeKernels() != bake::Kernels::Avx512)
    GTEST_SKIP() << "no AVX-512 on this CPU: atMany looks each hit up with at()";
  std::mt19937 rng(7);
  const Scene s = randomScene(rng);

  // Hits on every instance, barycentrics inside the triangle and on its edges and corners.
  const size_t hits = 4000;
  std::vector<uint32_t> mesh(hits), tri(hits);
  std::vector<float> b1(hits), b2(hits);
  std::uniform_int_distribution<uint32_t> anyMesh(0, uint32_t(s.meshes.size() - 1)), edge(0, 9);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (size_t h = 0; h < hits; ++h) {
    mesh[h] = anyMesh(rng);
    tri[h] = std::uniform_int_distribution<uint32_t>(0, uint32_t(s.meshes[mesh[h]].triangleCount() - 1))(rng);
    b1[h] = unit(rng), b2[h] = unit(rng) * (1.0f - b1[h]);
    if (edge(rng) == 0) b1[h] = 0.0f;
    if (edge(rng) == 0) b2[h] = 1.0f - b1[h];
  }
  const bake::AlbedoLookup lookup(s);
  // 1003 of them (blocks of 256 and a partial batch of 8), then all.
  for (uint32_t n : {1003u, uint32_t(hits)}) {
    std::vector<glm::vec3> many(n);
    lookup.atMany(mesh.data(), tri.data(), b1.data(), b2.data(), n, many.data());
    int wrong = 0;
    for (uint32_t h = 0; h < n; ++h) {
      const glm::vec3 one = lookup.at(mesh[h], tri[h], b1[h], b2[h]);
      if (std::memcmp(&one, &many[h], sizeof one) != 0 && ++wrong <= 5)
        ADD_FAILURE() << "hit " << h << " on instance " << mesh[h] << ": at() (" << one.r << ", " << one.g << ", "
                      << one.b << "), atMany (" << many[h].r << ", " << many[h].g << ", " << many[h].b << ")";
    }
    EXPECT_EQ(wrong, 0) << "of " << n;
  }
}

// The bounces' lookups (VaryingColours) hand out the colours of a vertex's hit records on
// varying instances in the records' order, a window of 4 096 at a time: over windows, from any
// first record, and started again on other records, each the colour at() gives.
TEST(AlbedoLookup, VaryingColoursFollowTheRecords) {
  std::mt19937 rng(11);
  const Scene s = randomScene(rng);
  const bake::Layout lay = bake::makeLayout(s);
  ASSERT_GT(lay.triangles, lay.frontTriangles) << "the scene should have back sides";
  const bake::AlbedoLookup lookup(s);
  std::vector<bake::HitRecord> hits(10000);
  for (bake::HitRecord& r : hits) {
    r.tri = uint32_t(rng() % lay.triangles);
    r.b1 = uint16_t(rng() % 65536);
    r.b2 = uint16_t(rng() % (65536 - r.b1));
  }
  bake::VaryingColours colours;
  for (auto [first, last] : {std::pair<uint32_t, uint32_t>{37, 10000}, {5, 9000}, {100, 100}, {0, 10000}}) {
    colours.start(lookup, lay, hits.data(), first, last);
    int wrong = 0, varying = 0;
    for (uint32_t h = first; h < last; ++h) {
      const uint32_t mesh = lay.meshOfTri[hits[h].tri];
      if (lookup.uniform[mesh]) continue;
      ++varying;
      const glm::vec3 want = lookup.at(mesh, lay.localTriangle(hits[h].tri), hits[h].b1 * (1.0f / 65535.0f),
                                       hits[h].b2 * (1.0f / 65535.0f));
      const glm::vec3 got = colours.next();
      if (std::memcmp(&want, &got, sizeof want) != 0 && ++wrong <= 5)
        ADD_FAILURE() << "record " << h << " of [" << first << ", " << last << ")";
    }
    EXPECT_EQ(wrong, 0);
    if (last - first > 8192) {
      EXPECT_GT(varying, int(bake::VaryingColours::kWindow)) << "more than a window";
    }
  }
}

}  // namespace
}  // namespace prt
