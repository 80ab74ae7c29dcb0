// The guards that keep the code's shape and catch bugs: PRT_DCHECK* (debug-only checks) and
// CheckContext (prt/error.h), and the shape gate tools/check_shape.sh run on small trees.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "harness.h"
#include "prt/error.h"

namespace prt::test {
int debugDcheckEvaluations();  // dcheck_debug.cpp: compiled without NDEBUG
void debugDcheckFails(int a, int b);
}  // namespace prt::test

namespace {

using prt::test::RunResult;
using prt::test::TempDir;

#ifdef NDEBUG
constexpr bool kDebugBuild = false;
#else
constexpr bool kDebugBuild = true;
#endif

// A check's failure aborts: the death test runs it in a fresh copy of the test program (threads
// that other tests of this process left would not survive a fork).
void threadsafeDeathTests() { GTEST_FLAG_SET(death_test_style, "threadsafe"); }

TEST(CoreCheck, DcheckIsEvaluatedOnlyWithoutNdebug) {
  int evaluations = 0;
  PRT_DCHECK(++evaluations > 0);
  PRT_DCHECK_EQ(++evaluations, kDebugBuild ? 2 : -1);
  PRT_DCHECK_GE(++evaluations, 0);
  EXPECT_EQ(evaluations, kDebugBuild ? 3 : 0) << "PRT_DCHECK must be evaluated exactly when NDEBUG is not set";
}

TEST(CoreCheck, DcheckFiresInADebugBuild) {
  threadsafeDeathTests();
  EXPECT_EQ(prt::test::debugDcheckEvaluations(), 2);
  EXPECT_DEATH(prt::test::debugDcheckFails(3, 4),
               "internal error at .*dcheck_debug.cpp:[0-9]+: CHECK\\(a == b\\) failed: 3 vs 4");
}

TEST(CoreCheck, DcheckIsCompiledOutWithNdebug) {
  if (kDebugBuild) GTEST_SKIP() << "this build has no NDEBUG";
  const int a = 1, b = 2;
  PRT_DCHECK_EQ(a, b);  // would abort if it ran
  PRT_DCHECK(a == b);
  SUCCEED();
}

TEST(CoreCheck, FailingCheckPrintsBothOperands) {
  threadsafeDeathTests();
  const int vertices = 3;
  EXPECT_DEATH(PRT_CHECK_LT(vertices, 2), "CHECK\\(vertices < 2\\) failed: 3 vs 2");
}

TEST(CoreCheck, ContextIsAddedToAFailingCheck) {
  threadsafeDeathTests();
  const auto fail = [] {
    const int instance = 4;
    const prt::CheckContext outer([&] { return prt::cat("instance ", instance); });
    for (int vertex = 0; vertex < 3; ++vertex) {
      const prt::CheckContext inner([&] { return prt::cat("vertex ", vertex); });
      PRT_CHECK_NE(vertex, 2);
    }
  };
  EXPECT_DEATH(fail(), "CHECK\\(vertex != 2\\) failed: 2 vs 2\nprt:   while: instance 4\nprt:   while: vertex 2\n");
}

TEST(CoreCheck, ContextIsCalledOnlyWhenACheckFails) {
  int described = 0;
  {
    const prt::CheckContext context([&] {
      ++described;
      return std::string("never");
    });
    PRT_CHECK(described == 0);
    PRT_CHECK_EQ(described, 0);
  }
  EXPECT_EQ(described, 0);
}

TEST(CoreCheck, ContextEndsWithItsScope) {
  threadsafeDeathTests();
  const auto fail = [] {
    {
      const prt::CheckContext gone([] { return std::string("finished step"); });
    }
    PRT_CHECK(false);
  };
  // No "while:" line follows the check's own line.
  EXPECT_DEATH(fail(), "CHECK\\(false\\) failed\n$");
}

// --- tools/check_shape.sh -----------------------------------------------------------------

// A C++ function of `lines` lines in all (signature and closing brace included).
std::string functionOf(const std::string& name, int lines) {
  std::string s = "int " + name + "(int x) {\n";
  for (int i = 0; i < lines - 3; ++i) s += "  x += " + std::to_string(i) + ";\n";
  return s + "  return x;\n}\n";
}

// A tree that check_shape.sh accepts: short functions, short files, an empty allow-list.
void writeCleanTree(const TempDir& tree) {
  for (const char* dir : {"bake/src", "render/src", "probes/core/src", "tools"})
    std::filesystem::create_directories(tree.path() / dir);
  tree.write("bake/src/stage.cpp", "namespace prt::bake {\n" + functionOf("stage", 80) + "}\n");
  tree.write("render/src/pass.cpp", functionOf("pass", 20));
  tree.write("tools/shape_allowlist.txt", "# nothing is over its limit\n");
}

RunResult checkShape(const TempDir& tree) {
  return prt::test::run("bash", {prt::test::sourcePath("tools/check_shape.sh"), tree.path().string()});
}

class ToolsShapeGate : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!prt::test::onPath("ctags")) GTEST_SKIP() << "universal-ctags is not installed (tools/setup.sh installs it)";
  }
};

TEST_F(ToolsShapeGate, AcceptsATreeWithinItsLimits) {
  TempDir tree;
  writeCleanTree(tree);
  const RunResult r = checkShape(tree);
  EXPECT_EQ(r.status, 0) << r.err;
}

TEST_F(ToolsShapeGate, RefusesALongFunctionNamingIt) {
  TempDir tree;
  writeCleanTree(tree);
  tree.write(
      "tools/long_command.cpp",
      "struct Command {\n  int run(int x);\n};\nint Command::run(int x) { return x; }\n" + functionOf("runLong", 81));
  const RunResult r = checkShape(tree);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("tools/long_command.cpp:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("runLong is 81 lines"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("Command::run"), std::string::npos) << r.err;
}

TEST_F(ToolsShapeGate, AcceptsAnAllowListedFunctionAndNamesClasses) {
  TempDir tree;
  writeCleanTree(tree);
  tree.write("probes/core/src/long.cpp", "namespace prt {\nnamespace {\nstruct Reader {\n  int read(int x) {\n" +
                                             std::string(90, '\n') + "    return x;\n  }\n};\n}  // namespace\n}\n");
  EXPECT_EQ(checkShape(tree).status, 1);
  tree.write("tools/shape_allowlist.txt", "probes/core/src/long.cpp Reader::read  # too long for now\n");
  const RunResult r = checkShape(tree);
  EXPECT_EQ(r.status, 0) << r.err;
}

TEST_F(ToolsShapeGate, RefusesAnAllowListEntryThatIsNoLongerNeeded) {
  TempDir tree;
  writeCleanTree(tree);
  tree.write("tools/shape_allowlist.txt", "bake/src/stage.cpp stage\nrender/src/gone.cpp\n");
  const RunResult r = checkShape(tree);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("bake/src/stage.cpp stage is 80 lines or fewer now (or gone): delete its line"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("render/src/gone.cpp is within its limit now (or gone): delete its line"), std::string::npos)
      << r.err;
}

TEST_F(ToolsShapeGate, RefusesLongFilesByFolder) {
  TempDir tree;
  writeCleanTree(tree);
  tree.write("render/src/big.h", std::string(801, '\n'));
  tree.write("probes/core/src/big.cpp", std::string(701, '\n'));
  tree.write("tools/big.cpp", std::string(2000, '\n'));  // tools/ has no file limit
  const RunResult r = checkShape(tree);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("render/src/big.h: 801 lines (at most 800"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("probes/core/src/big.cpp: 701 lines (at most 700"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("tools/big.cpp"), std::string::npos) << r.err;
  tree.write("tools/shape_allowlist.txt", "render/src/big.h\nprobes/core/src/big.cpp\n");
  EXPECT_EQ(checkShape(tree).status, 0);
}

}  // namespace
