// The test harness itself (harness.h): arguments reach the program unsplit and unquoted,
// stdout and stderr come back apart, and the exit code, signal, environment, folder and
// standard input are what the test asked for.
#include <gtest/gtest.h>

#include <signal.h>

#include <filesystem>
#include <string>

#include "harness.h"

namespace prt::test {
namespace {

namespace fs = std::filesystem;

TEST(TestHarness, ArgumentsArePassedAsGiven) {
  const RunResult r = run("printf", {"[%s]", "a b", "it's", "\"q\"", "$HOME", "*", ""});
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.out, "[a b][it's][\"q\"][$HOME][*][]");
}

TEST(TestHarness, OutputAndErrorApartOrMerged) {
  const RunResult r = run("sh", {"-c", "echo out; echo err >&2; exit 3"});
  EXPECT_EQ(r.status, 3);
  EXPECT_EQ(r.out, "out\n");
  EXPECT_EQ(r.err, "err\n");
  const RunResult merged = run("sh", {"-c", "echo out; echo err >&2"}, {.mergeOutput = true});
  EXPECT_EQ(merged.out, "out\nerr\n");
  EXPECT_EQ(merged.err, "");
}

TEST(TestHarness, EnvironmentFolderAndInput) {
  const TempDir dir("harness dir 'quoted'");
  const RunResult env = run("sh", {"-c", "printf '%s,%s' \"$PRT_HARNESS_SET\" \"${HOME-unset}\""},
                            {.env = {{"PRT_HARNESS_SET", "a b"}, {"HOME", std::nullopt}}});
  EXPECT_EQ(env.out, "a b,unset");
  const RunResult pwd = run("pwd", {}, {.cwd = dir.path()});
  EXPECT_EQ(pwd.out, dir.path().string() + "\n");
  const RunResult cat = run("cat", {}, {.stdinText = std::string("line 1\nline 2\n")});
  EXPECT_EQ(cat.out, "line 1\nline 2\n");
  EXPECT_EQ(run("cat", {}).out, "");  // no input given: /dev/null
}

TEST(TestHarness, SignalsAndMissingPrograms) {
  Process sleeper("sleep", {"30"});
  sleeper.signal(SIGTERM);
  const RunResult r = sleeper.wait();
  EXPECT_EQ(r.status, 128 + SIGTERM);
  EXPECT_LT(r.seconds, 10.0);
  const RunResult missing = run("/nonexistent/program", {});
  EXPECT_EQ(missing.status, 127);
  EXPECT_NE(missing.err.find("/nonexistent/program"), std::string::npos) << missing.err;
  EXPECT_TRUE(onPath("sh"));
  EXPECT_FALSE(onPath("prt-no-such-program"));
}

// A path with spaces and quotes reaches prt whole: its one-line error names the file.
TEST(TestHarness, PrtGetsPathsWithSpacesAndQuotes) {
  const TempDir dir("harness prt");
  const std::string path = dir.write("a \"b\" 'c'.hdr", "not an image");
  const RunResult r = runPrt({"info", path});
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(lineCount(r.err), 1) << r.err;
  EXPECT_NE(r.err.find(path), std::string::npos) << r.err;
}

TEST(TestHarness, TempDirIsFreshAndRemoved) {
  fs::path kept;
  {
    const TempDir dir;
    kept = dir.path();
    EXPECT_TRUE(fs::is_directory(kept));
    EXPECT_TRUE(dir.entries().empty());
    dir.write("x", "y");
    EXPECT_EQ(dir.entries(), std::vector<std::string>{"x"});
    EXPECT_EQ(fileBytes(dir.file("x")), "y");
  }
  EXPECT_FALSE(fs::exists(kept));
  EXPECT_EQ(base64("Man"), "TWFu");
  EXPECT_EQ(base64("Ma"), "TWE=");
  EXPECT_EQ(base64("M"), "TQ==");
}

}  // namespace
}  // namespace prt::test
