// The fuzzers' seeds and every input they once crashed on (tests/fuzz/corpus/, tests/fuzz/regressions/,
// docs/robustness.md), replayed through the loaders as in the fuzz targets: label fuzz.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "fuzz/fuzz_rig.h"
#include "harness.h"
#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/image.h"
#include "prt/light_rig.h"
#include "prt/probe_grid.h"
#include "prt/scene.h"

namespace prt {
namespace {

namespace fs = std::filesystem;

// ---- Fuzzer seeds and regressions: each input loads or raises prt::Error, nothing else
// (run under ASan + UBSan in CI, this replays every crash the fuzzers found).

std::vector<fs::path> fuzzInputs(const std::string& target) {
  std::vector<fs::path> files;
  for (const char* kind : {"corpus", "regressions"}) {
    fs::path dir = fs::path(test::sourcePath("tests/fuzz")) / kind / target;
    if (!fs::exists(dir)) continue;
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file() && e.path().filename().string()[0] != '.') files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

template <class Load>
void replay(const std::string& target, Load&& load) {
  std::vector<fs::path> files = fuzzInputs(target);
  EXPECT_FALSE(files.empty()) << "no seeds for " << target;
  for (const fs::path& f : files) {
    SCOPED_TRACE(f.string());
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

// Light rigs: the whole check of fuzz_rig (finite SH at several frames, one-line messages).
TEST(FuzzRegressions, Rig) {
  const RigReadOptions options = fuzz::rigOptions();
  replay("rig", [&](const std::string& path) {
    std::string problem;
    EXPECT_NO_THROW(problem = fuzz::rigProblem(readFile(path), options));  // evaluate() must not throw
    EXPECT_EQ(problem, "");
  });
}

// The seeds themselves are valid files: the fuzzers start from inputs that load.
TEST(FuzzRegressions, SeedsLoad) {
  fs::path corpus = test::sourcePath("tests/fuzz/corpus");
  for (const auto& e : fs::directory_iterator(corpus / "gltf"))
    EXPECT_NO_THROW(loadSceneFromMemory("fuzz.gltf", readFile(e.path().string()))) << e.path();
  for (const auto& e : fs::directory_iterator(corpus / "image"))
    EXPECT_NO_THROW(loadHdrImage(e.path().string())) << e.path();
  for (const auto& e : fs::directory_iterator(corpus / "vdb"))
    EXPECT_NO_THROW(readProbeGrid(e.path().string())) << e.path();
  for (const auto& e : fs::directory_iterator(corpus / "rig"))
    EXPECT_NO_THROW(parseLightRigFromMemory(readFile(e.path().string()), "seed.json", fuzz::rigOptions())) << e.path();
}

}  // namespace
}  // namespace prt
