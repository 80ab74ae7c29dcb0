// Hostile input (docs/robustness.md): every loader refuses a crafted file with one prt::Error
// line that names the file and the element, before it allocates anything the file's numbers
// ask for. The CLI's side (exit 1, output left alone): test_cli.cpp, CliHostileInput; the
// fuzzers' seeds and regressions: test_fuzz_replay.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "harness.h"
#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/image.h"
#include "prt/light.h"
#include "prt/light_rig.h"
#include "prt/probe_grid.h"
#include "prt/scene.h"
#include "test_util.h"

namespace prt {
namespace {

using prt::test::base64;

namespace fs = std::filesystem;
using Json = nlohmann::json;

std::string floatBytes(const std::vector<float>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(float));
}

const std::vector<float> kTriangle = {0, 0, 0, 1, 0, 0, 0, 1, 0};

/// One triangle (POSITION in buffer 0, bytes 0..35) on node 0 of scene 0; `bufferUri` is the
/// buffer's URI (default: the bytes inline as a data: URI).
Json triangleDoc(const std::string& bufferUri = "") {
  std::string uri =
      bufferUri.empty() ? "data:application/octet-stream;base64," + base64(floatBytes(kTriangle)) : bufferUri;
  return {{"asset", {{"version", "2.0"}}},
          {"scene", 0},
          {"scenes", {{{"nodes", {0}}}}},
          {"nodes", {{{"mesh", 0}}}},
          {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}}}}}}}}},
          {"buffers", {{{"byteLength", 36}, {"uri", uri}}}},
          {"bufferViews", {{{"buffer", 0}, {"byteLength", 36}}}},
          {"accessors", {{{"bufferView", 0}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}}}}};
}

/// Adds `bytes` as a new buffer (data: URI) with one view and one accessor; returns the accessor.
int addAccessor(Json& doc, const std::string& bytes, int componentType, size_t count, const char* type) {
  doc["buffers"].push_back(
      {{"byteLength", bytes.size()}, {"uri", "data:application/octet-stream;base64," + base64(bytes)}});
  doc["bufferViews"].push_back({{"buffer", doc["buffers"].size() - 1}, {"byteLength", bytes.size()}});
  doc["accessors"].push_back({{"bufferView", doc["bufferViews"].size() - 1},
                              {"componentType", componentType},
                              {"count", count},
                              {"type", type}});
  return int(doc["accessors"].size()) - 1;
}

class HostileInput : public ::testing::Test {
 protected:
  void SetUp() override {
    tmp_.emplace();
    root_ = tmp_->path();
    dir_ = root_ / "scene";
    fs::create_directories(dir_);
  }
  void TearDown() override { tmp_.reset(); }

  std::string write(const std::string& name, const std::string& text, const fs::path& in = {}) {
    fs::path p = (in.empty() ? dir_ : in) / name;
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }
  std::string writeDoc(const std::string& name, const Json& doc) { return write(name, doc.dump()); }

  std::optional<test::TempDir> tmp_;
  fs::path root_, dir_;  // dir_: the scene folder, inside root_
};

/// `f` must throw prt::Error: one line naming the file (its name) and containing every part.
template <class F>
void expectError(F&& f, const std::string& file, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "no error for " << file;
  } catch (const Error& e) {
    std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    EXPECT_NE(what.find(fs::path(file).filename().string()), std::string::npos) << what;
    for (const std::string& part : parts) EXPECT_NE(what.find(part), std::string::npos) << what;
  }
}

void expectSceneError(const std::string& path, const std::vector<std::string>& parts, const LoadOptions& o = {}) {
  expectError([&] { loadScene(path, o); }, path, parts);
}

// ---- URIs: the scene's folder and nothing else, unless allowed

TEST_F(HostileInput, BufferUriOutsideTheFolderIsRefusedUnlessAllowed) {
  write("outside.bin", floatBytes(kTriangle), root_);
  std::string path = writeDoc("up.gltf", triangleDoc("../outside.bin"));
  expectSceneError(path, {"buffer 0: uri '../outside.bin' points outside the scene folder",
                          "refused unless external URIs are allowed"});
  LoadOptions allow;
  allow.allowExternalUris = true;
  EXPECT_EQ(loadScene(path, allow).meshes.size(), 1u);
  // A `..` that stays inside is fine.
  fs::create_directories(dir_ / "sub");
  write("inside.bin", floatBytes(kTriangle));
  EXPECT_EQ(loadScene(writeDoc("in.gltf", triangleDoc("sub/../inside.bin"))).meshes.size(), 1u);
}

TEST_F(HostileInput, AbsoluteUriIsRefusedUnlessAllowed) {
  std::string bin = write("abs.bin", floatBytes(kTriangle), root_);
  ASSERT_TRUE(fs::path(bin).is_absolute());
  std::string path = writeDoc("abs.gltf", triangleDoc(bin));
  expectSceneError(path, {"buffer 0: uri '" + bin + "' is an absolute path"});
  LoadOptions allow;
  allow.allowExternalUris = true;
  EXPECT_EQ(loadScene(path, allow).meshes.size(), 1u);  // read where the URI says
}

TEST_F(HostileInput, SymbolicLinkLeadingOutIsRefused) {
  write("target.bin", floatBytes(kTriangle), root_);
  fs::create_symlink(root_ / "target.bin", dir_ / "link.bin");
  expectSceneError(writeDoc("link.gltf", triangleDoc("link.bin")), {"buffer 0: uri 'link.bin' points outside"});
}

TEST_F(HostileInput, ImageUriOutsideTheFolderIsRefused) {
  Json doc = triangleDoc();
  doc["images"] = {{{"uri", "../../etc/passwd"}}};
  expectSceneError(writeDoc("image.gltf", doc), {"image 0: uri '../../etc/passwd' points outside the scene folder"});
}

TEST_F(HostileInput, UriSchemesOtherThanDataAreRefused) {
  expectSceneError(writeDoc("http.gltf", triangleDoc("http://example.com/x.bin")),
                   {"buffer 0: uri 'http://example.com/x.bin' uses scheme 'http'"});
  expectSceneError(writeDoc("file.gltf", triangleDoc("file:///etc/passwd")), {"buffer 0", "scheme 'file'"});
}

TEST_F(HostileInput, WorkingDirectoryIsNotSearched) {
  // tinygltf falls back to the working directory for a file missing from the scene's folder.
  write("cwd.bin", floatBytes(kTriangle), root_);
  std::string path = writeDoc("cwd.gltf", triangleDoc("cwd.bin"));
  fs::path old = fs::current_path();
  fs::current_path(root_);
  try {
    expectSceneError(path, {"cwd.bin", "outside the scene folder"});
  } catch (...) {
    fs::current_path(old);
    throw;
  }
  fs::current_path(old);
}

TEST_F(HostileInput, DevicesAndFoldersAreNotRead) {
  fs::create_directories(dir_ / "dir.bin");
  expectSceneError(writeDoc("dir.gltf", triangleDoc("dir.bin")), {"buffer 0: uri 'dir.bin' is not a regular file"});
  LoadOptions allow;
  allow.allowExternalUris = true;
  expectSceneError(writeDoc("dev.gltf", triangleDoc("/dev/zero")), {"buffer 0: uri '/dev/zero' is not a regular file"},
                   allow);
}

TEST_F(HostileInput, FromMemoryOnlyDataUrisAreRead) {
  EXPECT_EQ(loadSceneFromMemory("mem.gltf", triangleDoc().dump()).meshes.size(), 1u);
  expectError([&] { loadSceneFromMemory("mem.gltf", triangleDoc("x.bin").dump()); }, "mem.gltf",
              {"buffer 0: uri 'x.bin' refers to a file, but the document was read from memory"});
}

// ---- Structure: recursion, counts, sizes

TEST_F(HostileInput, DeeplyNestedJsonIsRefusedBeforeParsing) {
  Json doc = triangleDoc();
  std::string extras = std::string(100000, '[') + std::string(100000, ']');
  std::string text = doc.dump();
  text.insert(text.size() - 1, ",\"extras\":" + extras);
  expectSceneError(write("deep.gltf", text), {"JSON nested deeper than 64 levels"});
}

TEST_F(HostileInput, NodeHierarchyDeeperThanTheLimitIsRefused) {
  Json doc = triangleDoc();
  doc["nodes"] = Json::array();
  for (int i = 0; i < 1100; ++i) doc["nodes"].push_back({{"children", {i + 1}}});
  doc["nodes"].push_back({{"mesh", 0}});
  expectSceneError(writeDoc("chain.gltf", doc), {"node 1001", "deeper than 1000 levels"});
}

TEST_F(HostileInput, NodeReachedTwiceIsRefused) {
  Json doc = triangleDoc();
  doc["nodes"] = {{{"children", {2}}}, {{"children", {2}}}, {{"mesh", 0}}};
  doc["scenes"][0]["nodes"] = {0, 1};
  expectSceneError(writeDoc("dag.gltf", doc), {"node 2 is reached twice"});
}

TEST_F(HostileInput, AccessorWithoutBufferViewCannotAskForMemory) {
  Json doc = triangleDoc();
  doc["accessors"][0] = {{"componentType", 5126}, {"count", 4000000000LL}, {"type", "VEC3"}};
  expectSceneError(writeDoc("bufferless.gltf", doc),
                   {"mesh 0 / primitive 0 / POSITION: accessor 0 has 4000000000 elements but no buffer view"});
}

TEST_F(HostileInput, CountsOffsetsAndStridesThatOverflowAreRefused) {
  Json doc = triangleDoc();
  doc["accessors"][0]["count"] = 6148914691236517206ULL;  // (2^64 + 2) / 3: count·12 wraps
  expectSceneError(writeDoc("count.gltf", doc), {"POSITION: accessor 0", "runs past the end of buffer view 0"});
  doc = triangleDoc();
  doc["accessors"][0]["byteOffset"] = 18446744073709551612ULL;  // 2^64 - 4
  expectSceneError(writeDoc("offset.gltf", doc), {"POSITION", "runs past the end"});
  doc = triangleDoc();
  doc["bufferViews"][0]["byteStride"] = 8;  // smaller than a VEC3 of floats
  expectSceneError(writeDoc("stride.gltf", doc), {"POSITION", "byteStride"});
}

TEST_F(HostileInput, TooManyTransferCoefficientsAreRefused) {
  Json doc = triangleDoc();
  auto& attributes = doc["meshes"][0]["primitives"][0]["attributes"];
  for (int i = 0; i < 81; ++i) attributes[cat("_PRT_SH_", i < 10 ? "0" : "", i)] = 0;  // 9 bands
  expectSceneError(writeDoc("bands.gltf", doc), {"mesh 0 / primitive 0", "81 transfer attributes", "at most 64"});
}

// ---- Numbers: NaN and infinity wherever they would flow into the bake

TEST_F(HostileInput, NonFiniteNumbersAreRefused) {
  // JSON has no NaN, and nlohmann/json refuses 1e999 rather than read infinity...
  std::string text = triangleDoc().dump();
  text.insert(text.size() - 1, ",\"extras\":1e999");
  expectSceneError(write("inf.gltf", text), {"malformed glTF", "1e999"});
  // ... but doubles beyond float's range become infinite where prt stores them as float.
  Json doc = triangleDoc();
  doc["materials"] = {{{"pbrMetallicRoughness", {{"baseColorFactor", {1, 1e300, 1, 1}}}}}};
  doc["meshes"][0]["primitives"][0]["material"] = 0;
  expectSceneError(writeDoc("factor.gltf", doc), {"material 0: baseColorFactor is not finite"});
  doc = triangleDoc();
  doc["extensionsUsed"] = {"KHR_lights_punctual"};
  doc["extensions"]["KHR_lights_punctual"]["lights"] = {{{"type", "point"}, {"intensity", -1e300}}};
  doc["nodes"][0]["extensions"]["KHR_lights_punctual"]["light"] = 0;
  expectSceneError(writeDoc("light.gltf", doc), {"light 0 '", "intensity: not a finite number"});
  // Out of KHR_lights_punctual's ranges: the light and the field named.
  doc["extensions"]["KHR_lights_punctual"]["lights"] = {{{"type", "point"}, {"name", "Lamp"}, {"intensity", -2}}};
  expectSceneError(writeDoc("light_negative.gltf", doc), {"light 0 'Lamp': intensity -2: must be >= 0"});
  doc["extensions"]["KHR_lights_punctual"]["lights"] = {
      {{"type", "spot"}, {"name", "Spot"}, {"spot", {{"innerConeAngle", 0.8}, {"outerConeAngle", 0.5}}}}};
  expectSceneError(writeDoc("light_cone.gltf", doc),
                   {"light 0 'Spot': spot.innerConeAngle 0.8: the inner cone must be inside the outer cone (0.5)"});
  doc["extensions"]["KHR_lights_punctual"]["lights"] = {{{"type", "point"}, {"color", {1, -0.5, 1}}}};
  expectSceneError(writeDoc("light_colour.gltf", doc), {"color -0.5: must be >= 0"});
  doc = triangleDoc();
  doc["nodes"][0]["scale"] = {1e300, 1, 1};
  expectSceneError(writeDoc("scale.gltf", doc), {"POSITION: vertex 1 is not finite after the node transform"});
  doc = triangleDoc();
  doc["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1e308, 0, 1};
  doc["nodes"][0]["children"] = {1};
  doc["nodes"].push_back({{"mesh", 0}, {"translation", {0, 1e308, 0}}});
  doc["nodes"][0].erase("mesh");
  expectSceneError(writeDoc("sum.gltf", doc), {"node 1", "not finite after the node transform"});
}

TEST_F(HostileInput, NonFiniteVertexDataIsRefused) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  Json doc = triangleDoc();
  int colors = addAccessor(doc, floatBytes({1, 1, 1, 1, nan, 1, 1, 1, 1}), 5126, 3, "VEC3");
  doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = colors;
  expectSceneError(writeDoc("color.gltf", doc), {"mesh 0 / primitive 0 / COLOR_0: vertex 1 is not finite"});
  doc = triangleDoc();
  for (int i = 0; i < 4; ++i) {
    std::vector<float> t(9, 0.5f);
    if (i == 3) t[7] = inf;  // vertex 2
    doc["meshes"][0]["primitives"][0]["attributes"][cat("_PRT_SH_0", i)] =
        addAccessor(doc, floatBytes(t), 5126, 3, "VEC3");
  }
  expectSceneError(writeDoc("transfer.gltf", doc), {"mesh 0 / primitive 0 / _PRT_SH_03: vertex 2 is not finite"});
}

// ---- Textures: format and size from the header, before decoding

/// The first bytes of a PNG: signature and IHDR chunk (CRC left zero: stbi_info does not check it).
std::string pngHeader(uint32_t w, uint32_t h) {
  auto be = [](uint32_t v) {
    return std::string{char(v >> 24), char(v >> 16 & 255), char(v >> 8 & 255), char(v & 255)};
  };
  return std::string("\x89PNG\r\n\x1a\n", 8) + be(13) + "IHDR" + be(w) + be(h) + std::string("\x08\x06\0\0\0", 5) +
         be(0);
}

Json texturedDoc(const std::string& imageBytes) {
  Json doc = triangleDoc();
  int uv = addAccessor(doc, floatBytes({0, 0, 1, 0, 0, 1}), 5126, 3, "VEC2");
  doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = uv;
  doc["meshes"][0]["primitives"][0]["material"] = 0;
  doc["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}};
  doc["textures"] = {{{"source", 0}}};
  doc["images"] = {{{"uri", "data:image/png;base64," + base64(imageBytes)}}};
  return doc;
}

TEST_F(HostileInput, AbsurdTextureDimensionsAreRefusedFromTheHeader) {
  expectSceneError(writeDoc("wide.gltf", texturedDoc(pngHeader(20000, 100))),
                   {"texture 0 / image 0", "image 20000x100 is too large"});
  // Within the side limit, over the texel limit (2^26): 16384 x 8192 texels.
  expectSceneError(writeDoc("many.gltf", texturedDoc(pngHeader(16384, 8192))),
                   {"texture 0 / image 0", "image 16384x8192 is too large"});
  // Beyond 2^30 bytes stb_image refuses the header itself.
  expectSceneError(writeDoc("huge.gltf", texturedDoc(pngHeader(100000, 100000))),
                   {"texture 0 / image 0: cannot decode"});
}

TEST_F(HostileInput, TexturesOtherThanPngAndJpegAreRefused) {
  std::string bmp = "BM" + std::string(60, '\0');
  expectSceneError(writeDoc("bmp.gltf", texturedDoc(bmp)), {"texture 0 / image 0: not a PNG or JPEG image"});
}

// ---- Images and probe grids

TEST_F(HostileInput, ImageWithTooManyPixelsIsRefusedFromTheHeader) {
  // 20000 x 20000 is within the side limit and over the pixel limit; the file has no pixels.
  std::string path = write("many.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 20000 +X 20000\n");
  expectError([&] { loadHdrImage(path); }, path, {"image 20000x20000 is too large (at most 134217728 pixels)"});
}

TEST_F(HostileInput, ExrWithoutItsPixelChunksIsRefusedBeforeAllocating) {
  // A valid header for 8192 x 8192 float RGB and an offset table that points nowhere: the
  // reader must not allocate 800 MB before finding out.
  ImageRgb small(4, 4);
  std::string good = (dir_ / "good.exr").string();
  writeExr(good, small);
  std::string bytes = readFile(good);
  // Rewrite dataWindow and displayWindow (box2i: xmin, ymin, xmax, ymax) in place.
  for (const char* name : {"dataWindow", "displayWindow"}) {
    size_t at = bytes.find(name);
    ASSERT_NE(at, std::string::npos);
    at += std::strlen(name) + 1 + std::strlen("box2i") + 1 + 4;
    int32_t box[4] = {0, 0, 8191, 8191};
    std::memcpy(bytes.data() + at, box, sizeof box);
  }
  std::string path = write("holes.exr", bytes);
  expectError([&] { loadHdrImage(path); }, path, {"corrupt OpenEXR file"});
}

// ---- Light rigs (docs/lights.md, "Limits"): bytes, structure, numbers, and what they derive

std::string rigJson(const std::string& lights, const std::string& extra = "") {
  return "{\"version\": 1" + extra + ", \"lights\": [" + lights + "]}";
}

void expectRigError(const std::string& json, const std::vector<std::string>& parts, const RigReadOptions& o = {}) {
  expectError([&] { parseLightRigFromMemory(json, "rig.json", o); }, "rig.json", parts);
}

/// The message of the prt::Error that `f` throws ("" if none).
template <class F>
std::string messageOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

void expectFiniteSh(const LightRig& rig, double frame) {
  for (int bands : {1, 3, 8}) {
    sh::ShRgb l = rig.evaluate(frame, bands);
    for (const glm::vec3& c : l.c)
      ASSERT_TRUE(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z)) << "frame " << frame << ", " << bands;
  }
}

const std::string kUniform = R"({"type": "uniform", "radiance": 1})";

TEST_F(HostileInput, RigLargerThanTheSizeLimitIsRefusedBeforeReading) {
  // Exactly the limit loads (JSON allows any whitespace); one byte more does not, from a file
  // (checked on its size, before reading) or from memory.
  std::string json = rigJson(kUniform);
  json += std::string(RigLimits::kMaxFileBytes - json.size(), ' ');
  EXPECT_EQ(loadLightRig(write("limit.json", json)).lights.size(), 1u);
  json += ' ';
  expectError([&] { loadLightRig(write("over.json", json)); }, "over.json",
              {"16777217 bytes: larger than a rig may be (16777216 bytes)"});
  expectRigError(json, {"rig.json: 16777217 bytes: larger than a rig may be"});
}

TEST_F(HostileInput, RigNestedDeeperThan64IsRefusedBeforeParsing) {
  auto nested = [](int depth) { return std::string(depth, '[') + std::string(depth, ']'); };
  // The rig object is level 1: 63 more levels are read (and refused for what they are)...
  std::string e =
      messageOf([&] { parseLightRigFromMemory(rigJson(kUniform, ", \"description\": " + nested(63)), "rig.json"); });
  EXPECT_NE(e.find("rig.json: description: expected a string"), std::string::npos) << e;
  // ...64 are not, nor 100000 (which a recursive reader would not survive).
  expectRigError(rigJson(kUniform, ",\n \"description\": " + nested(64)),
                 {"rig.json: JSON nested deeper than 64 levels (line 2)"});
  expectRigError(rigJson(kUniform, ", \"description\": " + nested(100000)), {"JSON nested deeper than 64 levels"});
  // Brackets inside strings are text.
  EXPECT_NO_THROW(
      parseLightRigFromMemory(rigJson(kUniform, ", \"description\": \"" + std::string(1000, '[') + "\""), "r"));
}

TEST_F(HostileInput, RigNulBytesAndControlCharactersAreRefused) {
  std::string json = rigJson(kUniform);
  json[5] = '\0';
  expectRigError(json, {"rig.json: NUL byte at offset 5 (a rig is JSON text)"});
  // Escaped into a string: a path must not hold one (the file system would stop there), and a
  // message shows it escaped, on one line.
  RigReadOptions withMap;
  withMap.maps["sky.hdr"] = ImageRgb(2, 1);
  expectRigError(rigJson(R"({"type": "environment", "file": "sky.hdr\u0000.exr"})"),
                 {"lights[0].file: 'sky.hdr\\x00.exr': a path without control characters (or NUL) expected"}, withMap);
  expectRigError(rigJson(R"({"type": "environment", "file": "sky\n.hdr"})"), {"'sky\\x0a.hdr'"}, withMap);
  expectRigError(rigJson(R"({"type": "uniform", "radiance": 1, "a\u0000b\nc": 2})"),
                 {"lights[0].a\\x00b\\x0ac: unknown key"});
  expectRigError(rigJson(R"({"type": "sun\r\n"})"), {"lights[0].type: 'sun\\x0d\\x0a' is not a light type"});
}

TEST_F(HostileInput, RigNumbersBeyondTheLimitsAreRefused) {
  EXPECT_NO_THROW(parseLightRigFromMemory(rigJson(R"({"type": "uniform", "radiance": 1e12})"), "r"));
  EXPECT_NO_THROW(parseLightRigFromMemory(rigJson(R"({"type": "sun", "azimuth": -1e12, "elevation": 3})"), "r"));
  expectRigError(rigJson(R"({"type": "uniform", "radiance": [1, 2e12, 3]})"),
                 {"lights[0].radiance: 2e+12 is beyond ±1e+12"});
  expectRigError(
      rigJson(
          R"({"type": "sun", "azimuth": [{"frame": 0, "value": 1}, {"frame": 1, "value": -3e12}], "elevation": 3})"),
      {"lights[0].azimuth[1].value: -3e+12 is beyond ±1e+12"});
  expectRigError(rigJson(R"({"type": "sun", "direction": [0, 5e13, 0]})"), {"lights[0].direction: 5e+13 is beyond"});
  // JSON has no NaN or infinity, and a number beyond double's range is not read as one.
  expectRigError(rigJson(R"({"type": "uniform", "radiance": NaN})"), {"rig.json: invalid JSON: "});
  expectRigError(rigJson(R"({"type": "uniform", "radiance": -1e400})"),
                 {"invalid JSON: number overflow parsing '-1e400'"});
  // Frames: within ±1e9.
  EXPECT_NO_THROW(parseLightRigFromMemory(
      rigJson(R"({"type": "uniform", "radiance": [{"frame": -1e9, "value": 1}, {"frame": 1e9, "value": 2}]})"), "r"));
  expectRigError(
      rigJson(R"({"type": "uniform", "radiance": [{"frame": 0, "value": 1}, {"frame": 1.5e9, "value": 2}]})"),
      {"lights[0].radiance[1].frame: frame 1.5e+09 is beyond ±1e+09"});
  // Frames per second: [0.001, 10000].
  for (const char* fps : {"0.001", "24", "10000"})
    EXPECT_NO_THROW(parseLightRigFromMemory(rigJson(kUniform, std::string(", \"fps\": ") + fps), "r")) << fps;
  for (const char* fps : {"0.0009", "10001", "-24", "0"})
    expectRigError(rigJson(kUniform, std::string(", \"fps\": ") + fps),
                   {"fps: must be in [0.001, 10000] frames per second"});
  expectRigError(rigJson(kUniform, ", \"fps\": \"24\""), {"fps: expected a number, got \"24\""});
}

TEST_F(HostileInput, RigCountsOfLightsAndKeysAreBounded) {
  std::string lights = kUniform;
  for (size_t i = 1; i < RigLimits::kMaxLights; ++i) lights += "," + kUniform;
  EXPECT_EQ(parseLightRigFromMemory(rigJson(lights), "r").lights.size(), RigLimits::kMaxLights);
  expectRigError(rigJson(lights + "," + kUniform), {"rig.json: lights: 1025 lights (at most 1024)"});
  std::string keys;
  for (size_t k = 0; k < RigLimits::kMaxKeys; ++k) keys += cat(k ? "," : "", "{\"frame\":", k, ",\"value\":1}");
  LightRig many = parseLightRigFromMemory(rigJson(R"({"type": "uniform", "radiance": {"keys": [)" + keys + "]}}"), "r");
  EXPECT_EQ(many.lights[0].color.keys.size(), RigLimits::kMaxKeys);
  expectRigError(rigJson(R"({"type": "uniform", "radiance": {"keys": [)" + keys + R"(,{"frame":1e8,"value":1}]}})"),
                 {"lights[0].radiance.keys: 100001 keys (at most 100000)"});
}

TEST_F(HostileInput, RigBadEnumsAreNamedAndLongStringsCut) {
  expectRigError(rigJson(R"({"type": "Sun"})"),
                 {"lights[0].type: 'Sun' is not a light type (environment, sun, disk, uniform, point, spot or area)"});
  expectRigError(rigJson(kUniform, R"(, "window": "HANN")"), {"window: 'HANN': expected none, hann or lanczos"});
  expectRigError(rigJson(kUniform, R"(, "window": 3)"), {"window: expected \"none\", \"hann\" or \"lanczos\""});
  expectRigError(
      rigJson(R"({"type": "uniform", "radiance": {"interpolation": "cubic", "keys": [{"frame": 0, "value": 1}]}})"),
      {"lights[0].radiance.interpolation: 'cubic': expected linear or step"});
  expectRigError(
      rigJson(R"({"type": "uniform", "radiance": {"interpolation": 1, "keys": [{"frame": 0, "value": 1}]}})"),
      {"lights[0].radiance.interpolation: '1': expected linear or step"});
  // A string from the file is quoted in at most 40 bytes (cut on a UTF-8 boundary, "...").
  const std::string x(100000, 'x');
  for (const std::string& json :
       {rigJson("{\"type\": \"" + x + "\"}"), rigJson(kUniform, ", \"window\": \"" + x + "\""),
        rigJson(R"({"type": "uniform", "radiance": 1, ")" + x + "\": 1}"), rigJson("{\"type\": \"" + x + "\x01\"}"),
        rigJson("{\"type\": 1" + std::string(100000, '0') + "}"),
        rigJson(R"({"type": "uniform", "radiance": ")" + x + "\"}"),
        rigJson("{\"type\": \"" + std::string(30, 'x') + std::string(50, '\xc3') + "\"}")}) {
    std::string e = messageOf([&] { parseLightRigFromMemory(json, "rig.json"); });
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
    EXPECT_LT(e.size(), 250u) << e;  // the fixed text, and 40 bytes of the string
    EXPECT_TRUE(e.find(std::string(30, 'x')) != std::string::npos || e.find(std::string(30, '0')) != std::string::npos)
        << e;
  }
  std::string e = messageOf(
      [&] { parseLightRigFromMemory(rigJson("{\"type\": \"" + std::string(39, 'a') + "\xc3\xa9z\"}"), "r"); });
  EXPECT_NE(e.find("'" + std::string(39, 'a') + "\xc3\xa9...'"), std::string::npos) << e;
}

TEST_F(HostileInput, RigMissingFilesFoldersAndDevicesAreRefused) {
  expectError([] { loadLightRig("/nonexistent/rig.json"); }, "rig.json", {"/nonexistent/rig.json: no such file"});
  expectError([&] { loadLightRig(dir_.string()); }, dir_.string(), {"is a directory"});
  expectError([] { loadLightRig("/dev/zero"); }, "/dev/zero", {"/dev/zero: not a regular file"});
  // Maps too: a device would be read forever.
  std::string rig = write("dev.json", rigJson(R"({"type": "environment", "file": "/dev/zero"})"));
  expectError([&] { loadLightRig(rig); }, rig, {"lights[0].file: /dev/zero: not a regular file"});
  rig = write("missing.json", rigJson(R"({"type": "environment", "file": "nothere.hdr"})"));
  expectError([&] { loadLightRig(rig); }, rig,
              {"lights[0].file: " + (dir_ / "nothere.hdr").string() + ": no such file"});
}

TEST_F(HostileInput, RigFromMemoryReadsNoFileButMapsGivenInMemory) {
  std::string sky = write("sky.hdr", "");
  expectRigError(rigJson(R"({"type": "environment", "file": ")" + sky + "\"}"),
                 {"lights[0].file: '" + sky.substr(0, 40) + "...': a rig read from memory reads no files"});
  RigReadOptions o;
  ImageRgb map(8, 4);
  for (size_t i = 0; i < map.pixels.size(); ++i) map.pixels[i] = glm::vec3(float(i), 1.0f, 0.5f);
  o.maps["sky.hdr"] = map;
  LightRig rig = parseLightRigFromMemory(rigJson(R"({"type": "environment", "file": "sky.hdr"})"), "rig.json", o);
  sh::ShRgb expected = projectEnvironment(map, 3), got = rig.evaluate(0, 3);
  for (int i = 0; i < 9; ++i) EXPECT_EQ(got.c[i], expected.c[i]) << i;
}

// Note 3 of light.cpp: a sun whose radius is too small for the disk formula (s and sin² r
// underflow near 1e-154 rad and gave 0/0 = NaN) is the point sun, E · y_lm(d), in closed form.
TEST_F(HostileInput, RigTinySunRadiusGivesThePointSunNotNaN) {
  const glm::dvec3 d = glm::normalize(glm::dvec3(0.3, 0.9, -0.2));
  const double E = 1e12;
  double y[64];
  sh::evaluate(8, d, y);
  for (double degrees : {5e-324, 1e-300, 1e-160, 1e-100, 1e-20, 1e-8}) {
    for (const char* type : {"sun", "disk"}) {
      LightRig rig =
          parseLightRigFromMemory(rigJson(cat(R"({"type": ")", type, R"(", "direction": [0.3, 0.9, -0.2], "radius": )",
                                              degrees, R"(, "irradiance": 1e12})")),
                                  "rig.json");
      sh::ShRgb l = rig.evaluate(0, 8);
      for (int i = 0; i < 64; ++i)
        ASSERT_NEAR(l.c[i].x, E * y[i], 1e-6 * E) << type << " radius " << degrees << " coefficient " << i;
    }
  }
  // A disk of given radiance shrinks to nothing instead, until its radius is 0 in radians.
  LightRig disk = parseLightRigFromMemory(
      rigJson(R"({"type": "disk", "direction": [0, 1, 0], "radius": 1e-300, "radiance": 1e12})"), "r");
  expectFiniteSh(disk, 0.0);
  EXPECT_EQ(disk.evaluate(0, 3).c[0], glm::vec3(0.0f));
  expectRigError(rigJson(R"({"type": "disk", "direction": [0, 1, 0], "radius": 1e-323, "radiance": 1})"),
                 {"lights[0].radius: disk radius 9.88131e-324 degrees is 0 in radians"});
  // Either side of the switch to the point sun (1e-6 rad) the two agree to 7 r² (Note 3).
  const double r = 1e-6;
  sh::ShRgb below = projectSun(8, d, r * (1 - 1e-9), glm::dvec3(1.0)),
            above = projectSun(8, d, r * (1 + 1e-9), glm::dvec3(1.0));
  for (int i = 0; i < 64; ++i) EXPECT_NEAR(below.c[i].x, above.c[i].x, 2e-7) << i;
}

// Note of LightRig (light_rig.cpp): a map's SH stays finite in float when its brightest pixel,
// and that pixel times the intensity, stay within 1e30; 1024 such lights, turned, still do.
TEST_F(HostileInput, RigMapBrightnessIsBoundedSoItsShStaysFinite) {
  RigReadOptions o;
  ImageRgb hot(4, 2), hotter(4, 2), bright(4, 2);
  for (glm::vec3& p : hot.pixels) p = glm::vec3(9.99e29f);  // float(1e30) is a little above 1e30
  for (glm::vec3& p : hotter.pixels) p = glm::vec3(2e30f);
  bright.pixels[3] = glm::vec3(0.0f, 1e18f, 0.0f);
  o.maps = {{"hot.exr", hot}, {"hotter.exr", hotter}, {"bright.exr", bright}};
  const std::string turning =
      R"({"type": "environment", "file": "hot.exr", "axis": [1, 2, 3], "rotation": [{"frame": 0, "value": 0}, {"frame": 9, "value": 1e6}]})";
  std::string lights = turning;
  for (size_t i = 1; i < RigLimits::kMaxLights; ++i) lights += "," + turning;
  LightRig rig = parseLightRigFromMemory(rigJson(lights), "rig.json", o);
  for (double frame : {0.0, 3.7, 9.0}) expectFiniteSh(rig, frame);
  expectRigError(rigJson(R"({"type": "environment", "file": "hotter.exr"})"),
                 {"lights[0].file: brightest pixel 2e+30 is beyond 1e+30"}, o);
  // Maps given in memory are checked as maps read from files.
  o.maps["nan.exr"] = hot;
  o.maps["nan.exr"].pixels[5].y = std::nanf("");
  o.maps["inf.exr"] = hot;
  o.maps["inf.exr"].pixels[0].z = -INFINITY;
  expectRigError(rigJson(R"({"type": "environment", "file": "nan.exr"})"),
                 {"lights[0].file: a pixel is not a number (NaN)"}, o);
  expectRigError(rigJson(R"({"type": "environment", "file": "inf.exr"})"),
                 {"lights[0].file: brightest pixel inf is beyond 1e+30"}, o);
  expectRigError(rigJson(R"({"type": "environment", "file": "hot.exr", "intensity": [1, 1.5, 1]})"),
                 {"lights[0].intensity: intensity 1.5 times the map's brightest pixel 9.99e+29 is beyond 1e+30"}, o);
  EXPECT_NO_THROW(
      parseLightRigFromMemory(rigJson(R"({"type": "environment", "file": "bright.exr", "intensity": 1e12})"), "r", o));
  expectRigError(
      rigJson(
          R"({"type": "environment", "file": "bright.exr", "intensity": [{"frame": 0, "value": 1}, {"frame": 1, "value": [1, 1, 1e12]}, {"frame": 2, "value": 1e13}]})"),
      {"lights[0].intensity[2].value: 1e+13 is beyond ±1e+12"}, o);
}

// Linear keys interpolate inside their range exactly: two keys at the largest sun radius below
// 90° gave 90° between them at 1 frame in 10 (rounding), which projectSun refuses.
TEST_F(HostileInput, RigInterpolatedValuesStayInTheKeysRange) {
  const double r = std::nextafter(90.0, 0.0);
  LightRig rig = parseLightRigFromMemory(
      rigJson(R"({"type": "sun", "direction": [0, 1, 0], "radius": [{"frame": 0, "value": 89.999999999999986},
                                                                   {"frame": 7, "value": 89.999999999999986}]})"),
      "rig.json");
  ASSERT_EQ(rig.lights[0].radius.keys[1].value.x, r);
  for (int i = 0; i <= 1000; ++i) {
    const double frame = 7.0 * i / 1000;
    EXPECT_LT(rig.lights[0].radius.scalarAt(frame), 90.0) << frame;
    EXPECT_NO_THROW(rig.evaluate(frame, 3)) << frame;
  }
}

}  // namespace
}  // namespace prt
