// Hostile input (docs/robustness.md): every loader refuses a crafted file with one prt::Error
// line that names the file and the element, before it allocates anything the file's numbers
// ask for; the CLI exits 1 and leaves its output alone. Also replays the fuzzers' seeds and
// every input they once crashed on (tests/fuzz/regressions/).
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/image.h"
#include "prt/probe_grid.h"
#include "prt/scene.h"

namespace prt {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

std::string base64(const std::string& in) {
  static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < in.size(); i += 3) {
    uint32_t n = uint32_t(uint8_t(in[i])) << 16;
    if (i + 1 < in.size()) n |= uint32_t(uint8_t(in[i + 1])) << 8;
    if (i + 2 < in.size()) n |= uint32_t(uint8_t(in[i + 2]));
    out += digits[(n >> 18) & 63];
    out += digits[(n >> 12) & 63];
    out += i + 1 < in.size() ? digits[(n >> 6) & 63] : '=';
    out += i + 2 < in.size() ? digits[n & 63] : '=';
  }
  return out;
}

std::string floatBytes(const std::vector<float>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(float));
}

const std::vector<float> kTriangle = {0, 0, 0, 1, 0, 0, 0, 1, 0};

/// One triangle (POSITION in buffer 0, bytes 0..35) on node 0 of scene 0; `bufferUri` is the
/// buffer's URI (default: the bytes inline as a data: URI).
Json triangleDoc(const std::string& bufferUri = "") {
  std::string uri = bufferUri.empty() ? "data:application/octet-stream;base64," + base64(floatBytes(kTriangle))
                                      : bufferUri;
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
  doc["buffers"].push_back({{"byteLength", bytes.size()},
                            {"uri", "data:application/octet-stream;base64," + base64(bytes)}});
  doc["bufferViews"].push_back({{"buffer", doc["buffers"].size() - 1}, {"byteLength", bytes.size()}});
  doc["accessors"].push_back(
      {{"bufferView", doc["bufferViews"].size() - 1}, {"componentType", componentType}, {"count", count}, {"type", type}});
  return int(doc["accessors"].size()) - 1;
}

class Hostile : public ::testing::Test {
protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::path(::testing::TempDir()) / (std::string("prt_hostile_") + info->name());
    fs::remove_all(root_);
    dir_ = root_ / "scene";
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(root_); }

  std::string write(const std::string& name, const std::string& text, const fs::path& in = {}) {
    fs::path p = (in.empty() ? dir_ : in) / name;
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }
  std::string writeDoc(const std::string& name, const Json& doc) { return write(name, doc.dump()); }

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

TEST_F(Hostile, BufferUriOutsideTheFolderIsRefusedUnlessAllowed) {
  write("outside.bin", floatBytes(kTriangle), root_);
  std::string path = writeDoc("up.gltf", triangleDoc("../outside.bin"));
  expectSceneError(path, {"buffer 0: uri '../outside.bin' points outside the scene folder", "--allow-external-uris"});
  LoadOptions allow;
  allow.allowExternalUris = true;
  EXPECT_EQ(loadScene(path, allow).meshes.size(), 1u);
  // A `..` that stays inside is fine.
  fs::create_directories(dir_ / "sub");
  write("inside.bin", floatBytes(kTriangle));
  EXPECT_EQ(loadScene(writeDoc("in.gltf", triangleDoc("sub/../inside.bin"))).meshes.size(), 1u);
}

TEST_F(Hostile, AbsoluteUriIsRefusedUnlessAllowed) {
  std::string bin = write("abs.bin", floatBytes(kTriangle), root_);
  ASSERT_TRUE(fs::path(bin).is_absolute());
  std::string path = writeDoc("abs.gltf", triangleDoc(bin));
  expectSceneError(path, {"buffer 0: uri '" + bin + "' is an absolute path"});
  LoadOptions allow;
  allow.allowExternalUris = true;
  EXPECT_EQ(loadScene(path, allow).meshes.size(), 1u);  // read where the URI says
}

TEST_F(Hostile, SymbolicLinkLeadingOutIsRefused) {
  write("target.bin", floatBytes(kTriangle), root_);
  fs::create_symlink(root_ / "target.bin", dir_ / "link.bin");
  expectSceneError(writeDoc("link.gltf", triangleDoc("link.bin")), {"buffer 0: uri 'link.bin' points outside"});
}

TEST_F(Hostile, ImageUriOutsideTheFolderIsRefused) {
  Json doc = triangleDoc();
  doc["images"] = {{{"uri", "../../etc/passwd"}}};
  expectSceneError(writeDoc("image.gltf", doc), {"image 0: uri '../../etc/passwd' points outside the scene folder"});
}

TEST_F(Hostile, UriSchemesOtherThanDataAreRefused) {
  expectSceneError(writeDoc("http.gltf", triangleDoc("http://example.com/x.bin")),
                   {"buffer 0: uri 'http://example.com/x.bin' uses scheme 'http'"});
  expectSceneError(writeDoc("file.gltf", triangleDoc("file:///etc/passwd")), {"buffer 0", "scheme 'file'"});
}

TEST_F(Hostile, WorkingDirectoryIsNotSearched) {
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

TEST_F(Hostile, DevicesAndFoldersAreNotRead) {
  fs::create_directories(dir_ / "dir.bin");
  expectSceneError(writeDoc("dir.gltf", triangleDoc("dir.bin")), {"buffer 0: uri 'dir.bin' is not a regular file"});
  LoadOptions allow;
  allow.allowExternalUris = true;
  expectSceneError(writeDoc("dev.gltf", triangleDoc("/dev/zero")), {"buffer 0: uri '/dev/zero' is not a regular file"},
                   allow);
}

TEST_F(Hostile, FromMemoryOnlyDataUrisAreRead) {
  EXPECT_EQ(loadSceneFromMemory("mem.gltf", triangleDoc().dump()).meshes.size(), 1u);
  expectError([&] { loadSceneFromMemory("mem.gltf", triangleDoc("x.bin").dump()); }, "mem.gltf",
              {"buffer 0: uri 'x.bin' refers to a file, but the document was read from memory"});
}

// ---- Structure: recursion, counts, sizes

TEST_F(Hostile, DeeplyNestedJsonIsRefusedBeforeParsing) {
  Json doc = triangleDoc();
  std::string extras = std::string(100000, '[') + std::string(100000, ']');
  std::string text = doc.dump();
  text.insert(text.size() - 1, ",\"extras\":" + extras);
  expectSceneError(write("deep.gltf", text), {"JSON nested deeper than 64 levels"});
}

TEST_F(Hostile, NodeHierarchyDeeperThanTheLimitIsRefused) {
  Json doc = triangleDoc();
  doc["nodes"] = Json::array();
  for (int i = 0; i < 1100; ++i) doc["nodes"].push_back({{"children", {i + 1}}});
  doc["nodes"].push_back({{"mesh", 0}});
  expectSceneError(writeDoc("chain.gltf", doc), {"node 1001", "deeper than 1000 levels"});
}

TEST_F(Hostile, NodeReachedTwiceIsRefused) {
  Json doc = triangleDoc();
  doc["nodes"] = {{{"children", {2}}}, {{"children", {2}}}, {{"mesh", 0}}};
  doc["scenes"][0]["nodes"] = {0, 1};
  expectSceneError(writeDoc("dag.gltf", doc), {"node 2 is reached twice"});
}

TEST_F(Hostile, AccessorWithoutBufferViewCannotAskForMemory) {
  Json doc = triangleDoc();
  doc["accessors"][0] = {{"componentType", 5126}, {"count", 4000000000LL}, {"type", "VEC3"}};
  expectSceneError(writeDoc("bufferless.gltf", doc),
                   {"mesh 0 / primitive 0 / POSITION: accessor 0 has 4000000000 elements but no buffer view"});
}

TEST_F(Hostile, CountsOffsetsAndStridesThatOverflowAreRefused) {
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

TEST_F(Hostile, TooManyTransferCoefficientsAreRefused) {
  Json doc = triangleDoc();
  auto& attributes = doc["meshes"][0]["primitives"][0]["attributes"];
  for (int i = 0; i < 81; ++i) attributes[cat("_PRT_SH_", i < 10 ? "0" : "", i)] = 0;  // 9 bands
  expectSceneError(writeDoc("bands.gltf", doc), {"mesh 0 / primitive 0", "81 transfer attributes", "at most 64"});
}

// ---- Numbers: NaN and infinity wherever they would flow into the bake

TEST_F(Hostile, NonFiniteNumbersAreRefused) {
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
  expectSceneError(writeDoc("light.gltf", doc), {"light 0: a parameter is not finite"});
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

TEST_F(Hostile, NonFiniteVertexDataIsRefused) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  Json doc = triangleDoc();
  int colors = addAccessor(doc, floatBytes({1, 1, 1, 1, nan, 1, 1, 1, 1}), 5126, 3, "VEC3");
  doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = colors;
  expectSceneError(writeDoc("color.gltf", doc), {"mesh 0 / primitive 0 / COLOR_0: vertex 1 is not finite"});
  doc = triangleDoc();
  for (int i = 0; i < 4; ++i) {
    std::vector<float> t(9, 0.5f);
    if (i == 3) t[7] = inf;  // vertex 2
    doc["meshes"][0]["primitives"][0]["attributes"][cat("_PRT_SH_0", i)] = addAccessor(doc, floatBytes(t), 5126, 3, "VEC3");
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

TEST_F(Hostile, AbsurdTextureDimensionsAreRefusedFromTheHeader) {
  expectSceneError(writeDoc("wide.gltf", texturedDoc(pngHeader(20000, 100))),
                   {"texture 0 / image 0", "image 20000x100 is too large"});
  // Within the side limit, over the texel limit (2^26): 16384 x 8192 texels.
  expectSceneError(writeDoc("many.gltf", texturedDoc(pngHeader(16384, 8192))),
                   {"texture 0 / image 0", "image 16384x8192 is too large"});
  // Beyond 2^30 bytes stb_image refuses the header itself.
  expectSceneError(writeDoc("huge.gltf", texturedDoc(pngHeader(100000, 100000))), {"texture 0 / image 0: cannot decode"});
}

TEST_F(Hostile, TexturesOtherThanPngAndJpegAreRefused) {
  std::string bmp = "BM" + std::string(60, '\0');
  expectSceneError(writeDoc("bmp.gltf", texturedDoc(bmp)), {"texture 0 / image 0: not a PNG or JPEG image"});
}

// ---- Images and probe grids

TEST_F(Hostile, ImageWithTooManyPixelsIsRefusedFromTheHeader) {
  // 20000 x 20000 is within the side limit and over the pixel limit; the file has no pixels.
  std::string path = write("many.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 20000 +X 20000\n");
  expectError([&] { loadHdrImage(path); }, path, {"image 20000x20000 is too large (at most 134217728 pixels)"});
}

TEST_F(Hostile, ExrWithoutItsPixelChunksIsRefusedBeforeAllocating) {
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

// ---- The command line: one line, exit 1, the output left as it was

struct CliRun {
  int status = -1;
  std::string err;
};

CliRun runPrt(const std::string& args, const fs::path& dir) {
  std::string errFile = (dir / "stderr.txt").string();
  int rc = std::system((std::string(PRT_EXE) + " " + args + " >/dev/null 2>" + errFile).c_str());
  CliRun r;
  r.status = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  r.err = readFile(errFile);
  fs::remove(errFile);
  return r;
}

TEST_F(Hostile, CliRefusesOutsideUriLeavesOutputsAloneAndAllowsOnRequest) {
  write("outside.bin", floatBytes(kTriangle), root_);
  std::string scene = writeDoc("up.gltf", triangleDoc("../outside.bin"));
  fs::path out = root_ / "out";
  fs::create_directories(out);
  std::string glb = (out / "up.glb").string(), vdb = (out / "up.vdb").string();
  write("up.glb", "previous contents", out);  // an earlier result must survive a failed run
  CliRun r = runPrt("bake " + scene + " -o " + glb + " --probes " + vdb + " --samples 16 -q", root_);
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find("up.gltf: buffer 0: uri '../outside.bin' points outside"), std::string::npos) << r.err;
  EXPECT_EQ(readFile(glb), "previous contents");
  EXPECT_FALSE(fs::exists(vdb));
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(out)) left.push_back(e.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{"up.glb"}) << "temporary files left behind";

  CliRun ok = runPrt("bake " + scene + " -o " + glb + " --samples 16 -q --allow-external-uris", root_);
  EXPECT_EQ(ok.status, 0) << ok.err;
  EXPECT_EQ(loadScene(glb).meshes.size(), 1u);  // the baked file embeds the buffer
}

TEST_F(Hostile, CliRefusesCorruptInputsOfEveryCommand) {
  fs::path out = root_ / "out";
  fs::create_directories(out);
  std::string deep = write("deep.gltf", "{\"asset\":{\"version\":\"2.0\"},\"extras\":" + std::string(5000, '[') +
                                            std::string(5000, ']') + "}");
  std::string hdr = write("many.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 20000 +X 20000\n");
  std::string vdb = write("cut.vdb", std::string(" BDV\0\0\0\0\xdc\0\0\0", 12));
  const std::pair<std::string, std::string> cases[] = {
      {"bake " + deep + " -o " + (out / "a.glb").string() + " -q", "deep.gltf: JSON nested deeper"},
      {"light " + hdr + " -o " + (out / "l.json").string(), "many.hdr: image 20000x20000 is too large"},
      {"probe " + vdb + " --at 0,0,0", "cut.vdb: corrupt or truncated"},
      {"info " + deep, "deep.gltf: JSON nested deeper"},
  };
  for (const auto& [args, message] : cases) {
    CliRun r = runPrt(args, root_);
    EXPECT_EQ(r.status, 1) << args << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
  }
  EXPECT_TRUE(fs::is_empty(out));
}

// ---- Fuzzer seeds and regressions: each input loads or raises prt::Error, nothing else
// (run under ASan + UBSan in CI, this replays every crash the fuzzers found).

std::vector<fs::path> fuzzInputs(const std::string& target) {
  std::vector<fs::path> files;
  for (const char* kind : {"corpus", "regressions"}) {
    fs::path dir = fs::path(PRT_SOURCE_DIR) / "tests" / "fuzz" / kind / target;
    if (!fs::exists(dir)) continue;
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file() && e.path().filename().string()[0] != '.') files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAsan = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAsan = true;
#else
constexpr bool kAsan = false;
#endif
#else
constexpr bool kAsan = false;
#endif

template <class Load>
void replay(const std::string& target, Load&& load) {
  std::vector<fs::path> files = fuzzInputs(target);
  EXPECT_FALSE(files.empty()) << "no seeds for " << target;
  for (const fs::path& f : files) {
    SCOPED_TRACE(f.string());
    // bad_alloc_*: a library asks for an impossible allocation, which must throw
    // std::bad_alloc (reported as a corrupt file); ASan's operator new aborts instead, so these
    // are replayed by the other builds (and by fuzz_vdb, which restores the standard new).
    if (kAsan && f.filename().string().rfind("bad_alloc_", 0) == 0) continue;
    try {
      load(f.string());
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
  }
}

TEST(FuzzRegressions, Gltf) {
  replay("gltf", [](const std::string& path) { loadSceneFromMemory("fuzz.gltf", readFile(path)); });
}

TEST(FuzzRegressions, Image) {
  replay("image", [](const std::string& path) { loadHdrImage(path); });
}

TEST(FuzzRegressions, Vdb) {
  replay("vdb", [](const std::string& path) { readProbeGrid(path); });
}

// The seeds themselves are valid files: the fuzzers start from inputs that load.
TEST(FuzzRegressions, SeedsLoad) {
  fs::path corpus = fs::path(PRT_SOURCE_DIR) / "tests" / "fuzz" / "corpus";
  for (const auto& e : fs::directory_iterator(corpus / "gltf"))
    EXPECT_NO_THROW(loadSceneFromMemory("fuzz.gltf", readFile(e.path().string()))) << e.path();
  for (const auto& e : fs::directory_iterator(corpus / "image"))
    EXPECT_NO_THROW(loadHdrImage(e.path().string())) << e.path();
  for (const auto& e : fs::directory_iterator(corpus / "vdb")) EXPECT_NO_THROW(readProbeGrid(e.path().string())) << e.path();
}

}  // namespace
}  // namespace prt
