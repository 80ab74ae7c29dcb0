// Compressed glTF (probes/scene/src/gltf_decode.cpp, image_webp.cpp): a Draco-encoded and a
// meshopt-encoded (KHR_mesh_quantization, as gltfpack writes it) copy of a test scene, made here
// with the encoders' own APIs, load to the geometry of the plain file within the quantisation and
// bake to its transfer; a WebP base colour texture reads back as its texels' linear values;
// corrupt streams and unknown required extensions are one clean error line.
#include <gtest/gtest.h>

#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>
#include <meshoptimizer.h>
#include <webp/encode.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "harness.h"
#include "prt/bake/surface_bake.h"
#include "prt/error.h"
#include "prt/math.h"
#include "prt/scene.h"
#include "test_scenes.h"

namespace prt {
namespace {

using Json = nlohmann::json;

constexpr int kFloat = 5126, kUnsignedInt = 5125, kUnsignedShort = 5123, kByte = 5120;

/// A glTF document built in code: one data: buffer (buffer 0) and the views into it.
struct Doc {
  Json j;
  std::string bin;

  Doc() {
    j = {{"asset", {{"version", "2.0"}}},
         {"scene", 0},
         {"scenes", Json::array({{{"nodes", {0}}}})},
         {"nodes", Json::array()},
         {"meshes", Json::array()},
         {"accessors", Json::array()},
         {"bufferViews", Json::array()},
         {"materials", Json::array({{{"pbrMetallicRoughness", {{"baseColorFactor", {0.6, 0.6, 0.6, 1.0}}}}}})}};
  }
  /// Appends bytes to buffer 0 (4-byte aligned); returns their offset.
  size_t append(const void* data, size_t size) {
    while (bin.size() % 4) bin.push_back('\0');
    const size_t offset = bin.size();
    bin.append(static_cast<const char*>(data), size);
    return offset;
  }
  int view(const void* data, size_t size, size_t stride = 0) {
    Json v = {{"buffer", 0}, {"byteOffset", append(data, size)}, {"byteLength", size}};
    if (stride) v["byteStride"] = stride;
    j["bufferViews"].push_back(v);
    return int(j["bufferViews"].size() - 1);
  }
  int accessor(Json a) {
    j["accessors"].push_back(std::move(a));
    return int(j["accessors"].size() - 1);
  }
  void require(const std::string& extension) {
    j["extensionsUsed"].push_back(extension);
    j["extensionsRequired"].push_back(extension);
  }
  std::string text() {
    const Json data = {{"byteLength", bin.size()},
                       {"uri", "data:application/octet-stream;base64," + test::base64(bin)}};
    if (!j.contains("buffers")) j["buffers"] = Json::array();
    j["buffers"].insert(j["buffers"].begin(), data);  // buffer 0
    return j.dump();
  }
};

/// The test scene: a hemisphere-like cavity (self-shadowing, so transfer varies over it).
MeshInstance testMesh() { return test::makeCavity(prt::kPi / 3, 10, 20); }

std::vector<float> flat(const std::vector<glm::vec3>& v) {
  std::vector<float> out;
  for (const glm::vec3& x : v) out.insert(out.end(), {x.x, x.y, x.z});
  return out;
}

Doc plainDoc(const MeshInstance& m) {
  Doc d;
  const std::vector<float> p = flat(m.positions), n = flat(m.normals);
  const int pos = d.accessor({{"bufferView", d.view(p.data(), p.size() * 4)},
                              {"componentType", kFloat},
                              {"count", m.vertexCount()},
                              {"type", "VEC3"}});
  const int nor = d.accessor({{"bufferView", d.view(n.data(), n.size() * 4)},
                              {"componentType", kFloat},
                              {"count", m.vertexCount()},
                              {"type", "VEC3"}});
  const int idx = d.accessor({{"bufferView", d.view(m.indices.data(), m.indices.size() * 4)},
                              {"componentType", kUnsignedInt},
                              {"count", m.indices.size()},
                              {"type", "SCALAR"}});
  d.j["meshes"].push_back(
      {{"primitives", {{{"attributes", {{"POSITION", pos}, {"NORMAL", nor}}}, {"indices", idx}, {"material", 0}}}}});
  d.j["nodes"].push_back({{"mesh", 0}});
  return d;
}

std::string plainFile(const MeshInstance& m) { return plainDoc(m).text(); }

constexpr int kDracoPositionBits = 14, kDracoNormalBits = 10;

/// The Draco bitstream of `m` (positions 14 bits, normals 10 bits, as common exporters do).
std::string dracoStream(const MeshInstance& m, int& positionId, int& normalId) {
  draco::TriangleSoupMeshBuilder b;
  b.Start(int(m.triangleCount()));
  const int pos = b.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const int nor = b.AddAttribute(draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32);
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    const uint32_t* i = &m.indices[3 * t];
    b.SetAttributeValuesForFace(pos, draco::FaceIndex(uint32_t(t)), &m.positions[i[0]], &m.positions[i[1]],
                                &m.positions[i[2]]);
    b.SetAttributeValuesForFace(nor, draco::FaceIndex(uint32_t(t)), &m.normals[i[0]], &m.normals[i[1]],
                                &m.normals[i[2]]);
  }
  std::unique_ptr<draco::Mesh> mesh = b.Finalize();
  positionId = int(mesh->attribute(pos)->unique_id());
  normalId = int(mesh->attribute(nor)->unique_id());
  draco::Encoder enc;
  enc.SetAttributeQuantization(draco::GeometryAttribute::POSITION, kDracoPositionBits);
  enc.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, kDracoNormalBits);
  draco::EncoderBuffer out;
  EXPECT_TRUE(enc.EncodeMeshToBuffer(*mesh, &out).ok());
  return std::string(out.data(), out.size());
}

std::string dracoFile(const MeshInstance& m, bool corrupt = false) {
  Doc d;
  int positionId = 0, normalId = 0;
  std::string stream = dracoStream(m, positionId, normalId);
  if (corrupt)
    for (size_t i = stream.size() / 3; i < stream.size(); ++i) stream[i] = char(0xA5 ^ i);
  const int view = d.view(stream.data(), stream.size());
  const int pos = d.accessor({{"componentType", kFloat}, {"count", m.vertexCount()}, {"type", "VEC3"}});
  const int nor = d.accessor({{"componentType", kFloat}, {"count", m.vertexCount()}, {"type", "VEC3"}});
  const int idx = d.accessor({{"componentType", kUnsignedInt}, {"count", m.indices.size()}, {"type", "SCALAR"}});
  Json draco = {{"bufferView", view}, {"attributes", {{"POSITION", positionId}, {"NORMAL", normalId}}}};
  d.j["meshes"].push_back({{"primitives",
                            {{{"attributes", {{"POSITION", pos}, {"NORMAL", nor}}},
                              {"indices", idx},
                              {"material", 0},
                              {"extensions", {{"KHR_draco_mesh_compression", draco}}}}}}});
  d.j["nodes"].push_back({{"mesh", 0}});
  d.require("KHR_draco_mesh_compression");
  return d.text();
}

constexpr int kMeshoptPositionBits = 14;

/// Quantised and meshopt-compressed as gltfpack writes it: positions unsigned 14-bit integers
/// whose dequantisation (scale, offset) is the node's transform, normals normalized bytes;
/// every buffer view decoded from buffer 0 into the fallback buffer 1, which has no data.
std::string meshoptFile(const MeshInstance& m, double& step, bool corrupt = false) {
  Doc d;
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (const glm::vec3& p : m.positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const float extent = glm::max(hi.x - lo.x, glm::max(hi.y - lo.y, hi.z - lo.z));
  step = extent / double((1 << kMeshoptPositionBits) - 1);
  std::vector<uint16_t> positions;  // xyz + padding: glTF vertex strides are multiples of 4
  std::vector<int8_t> normals;
  for (size_t v = 0; v < m.vertexCount(); ++v) {
    for (int c = 0; c < 3; ++c) positions.push_back(uint16_t(std::lround((m.positions[v][c] - lo[c]) / step)));
    positions.push_back(0);
    for (int c = 0; c < 3; ++c) normals.push_back(int8_t(std::lround(m.normals[v][c] * 127.0f)));
    normals.push_back(0);
  }
  size_t fallback = 0;
  auto compressed = [&](const std::vector<unsigned char>& stream, size_t stride, size_t count, const char* mode) {
    std::string bytes(stream.begin(), stream.end());
    if (corrupt) bytes.resize(bytes.size() / 2);
    Json ext = {{"buffer", 0},
                {"byteOffset", d.append(bytes.data(), bytes.size())},
                {"byteLength", bytes.size()},
                {"byteStride", stride},
                {"count", count},
                {"mode", mode}};
    Json v = {{"buffer", 1},
              {"byteOffset", fallback},
              {"byteLength", stride * count},
              {"extensions", {{"EXT_meshopt_compression", ext}}}};
    if (std::string(mode) == "ATTRIBUTES") v["byteStride"] = stride;
    fallback += (stride * count + 3) / 4 * 4;
    d.j["bufferViews"].push_back(v);
    return int(d.j["bufferViews"].size() - 1);
  };
  auto vertices = [&](const void* data, size_t stride) {
    std::vector<unsigned char> out(meshopt_encodeVertexBufferBound(m.vertexCount(), stride));
    out.resize(meshopt_encodeVertexBuffer(out.data(), out.size(), data, m.vertexCount(), stride));
    return compressed(out, stride, m.vertexCount(), "ATTRIBUTES");
  };
  const int posView = vertices(positions.data(), 8);
  const int norView = vertices(normals.data(), 4);
  std::vector<unsigned char> idx(meshopt_encodeIndexBufferBound(m.indices.size(), m.vertexCount()));
  idx.resize(meshopt_encodeIndexBuffer(idx.data(), idx.size(), m.indices.data(), m.indices.size()));
  const int idxView = compressed(idx, 4, m.indices.size(), "TRIANGLES");
  const int pos = d.accessor(
      {{"bufferView", posView}, {"componentType", kUnsignedShort}, {"count", m.vertexCount()}, {"type", "VEC3"}});
  const int nor = d.accessor({{"bufferView", norView},
                              {"componentType", kByte},
                              {"normalized", true},
                              {"count", m.vertexCount()},
                              {"type", "VEC3"}});
  const int ind = d.accessor(
      {{"bufferView", idxView}, {"componentType", kUnsignedInt}, {"count", m.indices.size()}, {"type", "SCALAR"}});
  d.j["meshes"].push_back(
      {{"primitives", {{{"attributes", {{"POSITION", pos}, {"NORMAL", nor}}}, {"indices", ind}, {"material", 0}}}}});
  d.j["nodes"].push_back({{"mesh", 0}, {"translation", {lo.x, lo.y, lo.z}}, {"scale", {step, step, step}}});
  d.j["buffers"] =
      Json::array({{{"byteLength", fallback}, {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}}});
  d.require("EXT_meshopt_compression");
  d.require("KHR_mesh_quantization");
  return d.text();
}

/// For each vertex of `b`, the vertex of `a` nearest to it (brute force: the meshes are small).
std::vector<size_t> nearestVertices(const MeshInstance& a, const MeshInstance& b) {
  std::vector<size_t> out;
  for (const glm::vec3& p : b.positions) {
    size_t best = 0;
    for (size_t v = 1; v < a.vertexCount(); ++v)
      if (glm::distance(a.positions[v], p) < glm::distance(a.positions[best], p)) best = v;
    out.push_back(best);
  }
  return out;
}

/// The compressed scene has the plain one's triangles, each vertex within `tolerance` of a
/// plain vertex with (within `normalTolerance`) its normal.
void expectSameGeometry(const Scene& plain, const Scene& other, float tolerance, float normalTolerance) {
  ASSERT_EQ(other.meshes.size(), 1u);
  const MeshInstance& a = plain.meshes[0];
  const MeshInstance& b = other.meshes[0];
  EXPECT_EQ(b.triangleCount(), a.triangleCount());
  const std::vector<size_t> match = nearestVertices(a, b);
  for (size_t v = 0; v < b.vertexCount(); ++v) {
    EXPECT_LE(glm::distance(a.positions[match[v]], b.positions[v]), tolerance) << "vertex " << v;
    EXPECT_LE(glm::distance(a.normals[match[v]], b.normals[v]), normalTolerance) << "vertex " << v;
  }
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(other.boundsMin[c], plain.boundsMin[c], tolerance);
    EXPECT_NEAR(other.boundsMax[c], plain.boundsMax[c], tolerance);
  }
}

bake::BakeSettings bakeSettings(uint64_t seed) {
  bake::BakeSettings s;
  s.samples = 256;
  s.bounces = 1;
  s.seed = seed;
  return s;
}

/// Mean over vertices of b and coefficients of |transfer_b - transfer_a| (b's vertices matched
/// to a's nearest).
double meanTransferDifference(const Scene& a, const bake::SurfaceTransfer& ta, const Scene& b,
                              const bake::SurfaceTransfer& tb) {
  const std::vector<size_t> match = nearestVertices(a.meshes[0], b.meshes[0]);
  const size_t k = 9;
  double sum = 0.0;
  for (size_t v = 0; v < match.size(); ++v)
    for (size_t i = 0; i < k; ++i) sum += glm::length(tb.perMesh[0][v * k + i] - ta.perMesh[0][match[v] * k + i]);
  return sum / double(match.size() * k);
}

/// The compressed copy bakes to the plain file's transfer: the mean difference is within the
/// estimator's own noise (the same bake with another seed), since a shift of the geometry by
/// the quantisation step (~1e-4 of the scene) moves transfer far less than 256 samples resolve.
/// A wrong decode (geometry off by the dequantisation, normals unnormalized) changes transfer
/// by its own size and fails this.
void expectSameTransfer(const Scene& plain, const Scene& other) {
  const bake::SurfaceTransfer reference = bake::bakeSurface(plain, bakeSettings(1));
  const bake::SurfaceTransfer reseeded = bake::bakeSurface(plain, bakeSettings(2));
  const bake::SurfaceTransfer decoded = bake::bakeSurface(other, bakeSettings(1));
  const double noise = meanTransferDifference(plain, reference, plain, reseeded);
  const double difference = meanTransferDifference(plain, reference, other, decoded);
  EXPECT_GT(noise, 0.0);
  EXPECT_LE(difference, 1.5 * noise) << "noise (seed 1 vs 2) " << noise;
}

void expectOneLineError(const std::string& name, const std::string& doc, const std::vector<std::string>& parts) {
  try {
    loadSceneFromMemory(name, doc);
    ADD_FAILURE() << "loaded";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    EXPECT_EQ(what.rfind(name + ": ", 0), 0u) << what;
    for (const std::string& p : parts) EXPECT_NE(what.find(p), std::string::npos) << what << "\nlacks: " << p;
  }
}

TEST(SceneDraco, LoadsToThePlainGeometryAndTransfer) {
  const MeshInstance m = testMesh();
  const Scene plain = loadSceneFromMemory("plain.gltf", plainFile(m));
  const Scene draco = loadSceneFromMemory("draco.gltf", dracoFile(m));
  // Draco quantises each axis over the bounding cube (side 2) in 2^14 - 1 steps: half a step
  // per axis; normals 10-bit octahedral, under 0.5° here.
  const float step = 2.0f / float((1 << kDracoPositionBits) - 1);
  expectSameGeometry(plain, draco, std::sqrt(3.0f) * step, 0.01f);
  expectSameTransfer(plain, draco);
  for (const std::string& w : draco.warnings) ADD_FAILURE() << w;
}

TEST(SceneDraco, CorruptStreamIsOneErrorNamingThePrimitive) {
  expectOneLineError("draco.gltf", dracoFile(testMesh(), true),
                     {"mesh 0 / primitive 0: KHR_draco_mesh_compression: corrupt Draco stream"});
}

TEST(SceneMeshopt, QuantizedLoadsToThePlainGeometryAndTransfer) {
  const MeshInstance m = testMesh();
  double step = 0.0;
  const Scene plain = loadSceneFromMemory("plain.gltf", plainFile(m));
  const Scene meshopt = loadSceneFromMemory("meshopt.gltf", meshoptFile(m, step));
  // Positions are rounded to the nearest step (half a step per axis) and then placed by the
  // node's scale and offset; normals are normalized bytes (1/127 per component).
  expectSameGeometry(plain, meshopt, float(std::sqrt(3.0) * 0.5 * step) * 1.01f, 0.02f);
  expectSameTransfer(plain, meshopt);
  for (const std::string& w : meshopt.warnings) ADD_FAILURE() << w;
}

TEST(SceneMeshopt, CorruptStreamIsOneErrorNamingTheBufferView) {
  double step = 0.0;
  expectOneLineError("meshopt.gltf", meshoptFile(testMesh(), step, true),
                     {"buffer view 0: EXT_meshopt_compression: corrupt ATTRIBUTES stream"});
}

TEST(SceneMeshopt, FallbackBufferWithoutCompressionIsOneError) {
  double step = 0.0;
  Json j = Json::parse(meshoptFile(testMesh(), step));
  j["bufferViews"][1].erase("extensions");  // now an ordinary view into the data-less buffer
  expectOneLineError("meshopt.gltf", j.dump(), {"buffer view 1", "fallback buffer, which holds no data"});
}

/// A 2×2 WebP (lossless, so the texels are exact) as a base colour texture required through
/// EXT_texture_webp, with no PNG fallback.
std::string base64Of(const std::string& bytes) {
  static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const size_t n = std::min<size_t>(3, bytes.size() - i);  // n bytes: n + 1 digits, then '='
    uint32_t v = 0;
    for (size_t k = 0; k < 3; ++k) v = (v << 8) | (k < n ? uint8_t(bytes[i + k]) : 0u);
    for (size_t k = 0; k < 4; ++k) out += k <= n ? digits[(v >> (18 - 6 * k)) & 63] : '=';
  }
  return out;
}

std::string webpFile(const std::vector<unsigned char>& rgba, bool corrupt = false, bool dataUri = false) {
  uint8_t* encoded = nullptr;
  const size_t size = WebPEncodeLosslessRGBA(rgba.data(), 2, 2, 8, &encoded);
  EXPECT_GT(size, 0u);
  std::string bytes(reinterpret_cast<const char*>(encoded), size);
  WebPFree(encoded);
  if (corrupt)
    for (size_t i = 20; i < bytes.size(); ++i) bytes[i] = char(0x5A ^ i);
  // In a buffer view, or as a data: URI (which tinygltf 2.7 refuses: prt moves it into a view).
  Doc d = plainDoc(testMesh());
  if (dataUri)
    d.j["images"] = Json::array({{{"uri", "data:image/webp;base64," + base64Of(bytes)}}});
  else
    d.j["images"] = Json::array({{{"bufferView", d.view(bytes.data(), bytes.size())}, {"mimeType", "image/webp"}}});
  Json j = Json::parse(d.text());
  j["textures"] = Json::array({{{"extensions", {{"EXT_texture_webp", {{"source", 0}}}}}}});
  j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}};
  j["extensionsUsed"] = {"EXT_texture_webp"};
  j["extensionsRequired"] = {"EXT_texture_webp"};
  return j.dump();
}

double srgbToLinear(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

TEST(SceneWebp, BaseColorTextureReadsAsLinearTexels) {
  const std::vector<unsigned char> rgba = {255, 0, 0,  255, 0,   128, 0,  255,
                                           0,   0, 64, 128, 200, 100, 50, 1};  // alpha 0 would let the encoder drop RGB
  const Scene s = loadSceneFromMemory("webp.gltf", webpFile(rgba));
  ASSERT_EQ(s.textures.size(), 1u);
  const Texture& t = s.textures[0];
  ASSERT_EQ(t.width, 2);
  ASSERT_EQ(t.height, 2);
  ASSERT_EQ(s.materials[0].baseColorTexture, 0);
  for (size_t i = 0; i < 4; ++i)
    for (int c = 0; c < 4; ++c) {
      const double x = rgba[4 * i + size_t(c)] / 255.0;
      EXPECT_NEAR(t.texels[i][c], c < 3 ? srgbToLinear(x) : x, 1e-6) << "texel " << i << " channel " << c;
    }
}

TEST(SceneWebp, DataUriReadsTheSameTexels) {
  const std::vector<unsigned char> rgba = {255, 0, 0, 255, 0, 128, 0, 255, 0, 0, 64, 128, 200, 100, 50, 1};
  const Scene inView = loadSceneFromMemory("webp.gltf", webpFile(rgba));
  const Scene inUri = loadSceneFromMemory("webp.gltf", webpFile(rgba, false, true));
  ASSERT_EQ(inUri.textures.size(), 1u);
  EXPECT_EQ(inUri.textures[0].width, 2);
  EXPECT_EQ(inUri.textures[0].texels, inView.textures[0].texels);
  expectOneLineError("webp.gltf", webpFile(std::vector<unsigned char>(16, 200), true, true), {"image 0", "WebP"});
  Json bad = Json::parse(webpFile(rgba, false, true));
  bad["images"][0]["uri"] = "data:image/webp;base64,@@@@";
  expectOneLineError("webp.gltf", bad.dump(), {"image 0", "not base64"});
}

TEST(SceneWebp, CorruptImageIsOneErrorNamingTheTexture) {
  expectOneLineError("webp.gltf", webpFile(std::vector<unsigned char>(16, 200), true), {"texture 0 / image 0", "WebP"});
}

TEST(SceneExtensions, UnsupportedRequiredExtensionIsNamedInOneLine) {
  Json j = Json::parse(plainFile(testMesh()));
  j["extensionsUsed"] = {"EXT_mesh_gpu_instancing", "KHR_mesh_quantization"};
  j["extensionsRequired"] = {"KHR_mesh_quantization", "EXT_mesh_gpu_instancing"};
  expectOneLineError("ext.gltf", j.dump(), {"required extension EXT_mesh_gpu_instancing is not supported"});
}

}  // namespace
}  // namespace prt
