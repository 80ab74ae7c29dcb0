#include "harness.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>

extern char** environ;

namespace prt::test {

namespace fs = std::filesystem;

namespace {

// The test's environment with `changes` applied, as "NAME=value" strings.
std::vector<std::string> environmentWith(const RunOptions& options) {
  std::vector<std::string> env;
  for (char** e = environ; *e; ++e) env.emplace_back(*e);
  for (const auto& [name, value] : options.env) {
    const std::string prefix = name + "=";
    env.erase(std::remove_if(env.begin(), env.end(), [&](const std::string& v) { return v.rfind(prefix, 0) == 0; }),
              env.end());
    if (value) env.push_back(prefix + *value);
  }
  return env;
}

std::vector<char*> pointers(std::vector<std::string>& strings) {
  std::vector<char*> p;
  for (std::string& s : strings) p.push_back(s.data());
  p.push_back(nullptr);
  return p;
}

// A folder of its own for one program's captured output (several may run at once).
fs::path makeCaptureDir() {
  std::string pattern = (fs::temp_directory_path() / "prt_run_XXXXXX").string();
  if (!::mkdtemp(pattern.data())) throw std::runtime_error(std::string("mkdtemp: ") + std::strerror(errno));
  return pattern;
}

void check(int rc, const char* what) {
  if (rc != 0) throw std::runtime_error(std::string(what) + ": " + std::strerror(rc));
}

}  // namespace

Process::Process(const std::string& exe, const std::vector<std::string>& args, const RunOptions& options)
    : captureDir_(makeCaptureDir()), start_(std::chrono::steady_clock::now()), mergeOutput_(options.mergeOutput) {
  const std::string in = options.stdinText ? (captureDir_ / "stdin").string() : "/dev/null";
  if (options.stdinText) std::ofstream(in, std::ios::binary) << *options.stdinText;
  const std::string out = (captureDir_ / "stdout").string(), err = (captureDir_ / "stderr").string();

  posix_spawn_file_actions_t actions;
  check(posix_spawn_file_actions_init(&actions), "posix_spawn_file_actions_init");
  check(posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, in.c_str(), O_RDONLY, 0), "addopen stdin");
  check(posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644),
        "addopen stdout");
  if (options.mergeOutput)
    check(posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO), "adddup2");
  else
    check(posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644),
          "addopen stderr");
  // Last, so that the capture paths above never depend on it.
  if (!options.cwd.empty()) check(posix_spawn_file_actions_addchdir_np(&actions, options.cwd.c_str()), "addchdir");

  std::vector<std::string> argStrings{exe};
  argStrings.insert(argStrings.end(), args.begin(), args.end());
  std::vector<std::string> envStrings = environmentWith(options);
  std::vector<char*> argv = pointers(argStrings), envp = pointers(envStrings);
  // A bare name is looked up on PATH, as a shell would; anything with a '/' is a path.
  const bool search = exe.find('/') == std::string::npos;
  const int rc = search ? ::posix_spawnp(&pid_, exe.c_str(), &actions, nullptr, argv.data(), envp.data())
                        : ::posix_spawn(&pid_, exe.c_str(), &actions, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    // As a shell reports a program it cannot run: exit 127 and one line on stderr.
    pid_ = -1;
    std::ofstream(err) << exe << ": cannot start: " << std::strerror(rc) << "\n";
  }
}

Process::~Process() {
  if (pid_ > 0) {
    ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
  }
  std::error_code ec;
  fs::remove_all(captureDir_, ec);
}

void Process::signal(int sig) const {
  if (pid_ > 0) ::kill(pid_, sig);
}

RunResult Process::wait() {
  RunResult r;
  if (pid_ > 0) {
    int status = 0;
    while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {}
    pid_ = -1;
    r.status = WIFEXITED(status) ? WEXITSTATUS(status) : WIFSIGNALED(status) ? 128 + WTERMSIG(status) : -1;
  } else {
    r.status = 127;
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  r.out = fileBytes(captureDir_ / "stdout");
  if (!mergeOutput_) r.err = fileBytes(captureDir_ / "stderr");
  return r;
}

RunResult run(const std::string& exe, const std::vector<std::string>& args, const RunOptions& options) {
  return Process(exe, args, options).wait();
}

std::string prtExe() { return PRT_EXE; }

RunResult runPrt(const std::vector<std::string>& args, const RunOptions& options) {
  return run(prtExe(), args, options);
}

std::string sourcePath(const std::string& relative) { return (fs::path(PRT_SOURCE_DIR) / relative).string(); }

bool onPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  if (!path) return false;
  std::string folders = path;
  for (size_t begin = 0; begin <= folders.size();) {
    size_t end = folders.find(':', begin);
    if (end == std::string::npos) end = folders.size();
    const fs::path dir = end > begin ? fs::path(folders.substr(begin, end - begin)) : fs::path(".");
    const fs::path candidate = dir / program;
    std::error_code ec;
    if (fs::is_regular_file(candidate, ec) && ::access(candidate.c_str(), X_OK) == 0) return true;
    begin = end + 1;
  }
  return false;
}

std::vector<std::string> plus(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

int lineCount(std::string_view text) { return int(std::count(text.begin(), text.end(), '\n')); }

TempDir::TempDir(const std::string& name) {
  static int counter = 0;
  std::string label = name;
  if (label.empty()) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    label = info ? std::string(info->test_suite_name()) + "_" + info->name() : "test";
  }
  std::replace(label.begin(), label.end(), '/', '_');  // parameterised tests: Suite/Name/0
  path_ = fs::temp_directory_path() /
          ("prt_test_" + label + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  fs::remove_all(path_);
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  if (::testing::Test::HasFailure()) {
    std::fprintf(stderr, "kept %s for a look (the test failed)\n", path_.c_str());
    return;
  }
  std::error_code ec;
  fs::remove_all(path_, ec);
}

std::string TempDir::write(const std::string& name, std::string_view bytes) const {
  const std::string p = file(name);
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}

std::vector<std::string> TempDir::entries() const {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(path_)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

std::string fileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::string base64(std::string_view in) {
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

std::string planeWithLamp(const std::filesystem::path& dir, double candela) {
  namespace fs = std::filesystem;
  fs::copy_file(sourcePath("scenes/plane.bin"), dir / "plane.bin", fs::copy_options::overwrite_existing);
  nlohmann::json j = nlohmann::json::parse(std::ifstream(sourcePath("scenes/plane.gltf")));
  j["extensionsUsed"] = {"KHR_lights_punctual"};
  j["extensions"]["KHR_lights_punctual"]["lights"] = {{{"name", "Lamp"}, {"type", "point"}, {"intensity", candela}}};
  j["nodes"].push_back(
      {{"name", "Lamp"}, {"translation", {0.0, 1.0, 0.0}}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  j["scenes"][0]["nodes"].push_back(int(j["nodes"].size()) - 1);
  const fs::path out = dir / "plane_lamp.gltf";
  std::ofstream(out) << j.dump();
  return out.string();
}

}  // namespace prt::test
