// What the tests share to run programs and keep files: one way to run the `prt` binary (or any
// other executable: vdb_print, python3, ffprobe) and capture what it says, one temporary folder,
// and the paths into the source tree. No shell is involved anywhere: arguments reach the program
// as they are given, so paths with spaces or quotes need no escaping.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace prt::test {

/// Built with AddressSanitizer: its allocator replaces malloc, and peaks and faults are its own.
#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kAddressSanitizer = true;
#else
inline constexpr bool kAddressSanitizer = false;
#endif
#else
inline constexpr bool kAddressSanitizer = false;
#endif

/// How a program is started. The environment is the test's own, changed by `env`: a value sets
/// the variable, std::nullopt removes it.
struct RunOptions {
  std::filesystem::path cwd;  ///< empty: the test's working folder
  std::vector<std::pair<std::string, std::optional<std::string>>> env;
  std::optional<std::string> stdinText;  ///< fed to standard input; without it, /dev/null
  bool mergeOutput = false;              ///< stderr into stdout (as `2>&1`): `out` holds both
};

/// What a finished program left.
struct RunResult {
  int status = -1;  ///< the exit code, or 128 + the signal that ended it (as a shell reports it)
  std::string out, err;
  double seconds = 0.0;  ///< from the start to the end of the program
};

/// A started program that runs while the test watches it (a bake to interrupt, to kill -9).
class Process {
 public:
  /// Starts `exe` with `args` (argv[1]...); a program that cannot be started exits 127.
  Process(const std::string& exe, const std::vector<std::string>& args, const RunOptions& options = {});
  ~Process();  ///< a program still running is killed and reaped
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const { return pid_; }
  void signal(int sig) const;
  /// Waits for the program to end and returns its status and output.
  RunResult wait();

 private:
  pid_t pid_ = -1;
  std::filesystem::path captureDir_;
  std::chrono::steady_clock::time_point start_;
  bool mergeOutput_ = false;
};

/// Runs `exe` (a path, or a name looked up on PATH) with `args` and waits for it.
RunResult run(const std::string& exe, const std::vector<std::string>& args, const RunOptions& options = {});

/// Runs the `prt` binary built with the tests.
RunResult runPrt(const std::vector<std::string>& args, const RunOptions& options = {});

/// The path of the `prt` binary built with the tests.
std::string prtExe();

/// An absolute path in the source tree: sourcePath("scenes/plane.gltf").
std::string sourcePath(const std::string& relative);

/// Whether `program` is an executable file in a folder of PATH.
bool onPath(const std::string& program);

/// `a` followed by `b`: a command line from its common part and the rest.
std::vector<std::string> plus(std::vector<std::string> a, const std::vector<std::string>& b);

/// The number of '\n' in `text`: a one-line message has exactly one.
int lineCount(std::string_view text);

/// A fresh, empty folder under the system's temporary folder, named after `name` (by default the
/// running test's suite and name) and the process, so that tests run in parallel processes never
/// share one. Removed when the object goes, unless the test failed: then kept for a look.
class TempDir {
 public:
  explicit TempDir(const std::string& name = "");
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  /// The path of `name` inside the folder, as a string (the form the command lines take).
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  /// Writes `bytes` to `name` inside the folder and returns its path.
  std::string write(const std::string& name, std::string_view bytes) const;
  /// The names in the folder, sorted.
  std::vector<std::string> entries() const;

 private:
  std::filesystem::path path_;
};

/// scenes/plane.gltf (2 m × 2 m at y = 0 facing +Y, albedo 0.8) with a KHR_lights_punctual point
/// light 'Lamp' of `candela` 1 m above its centre, written into `dir` (with its buffer) as
/// plane_lamp.gltf; returns its path.
std::string planeWithLamp(const std::filesystem::path& dir, double candela);

/// The whole content of a file as bytes ("" when it cannot be read).
std::string fileBytes(const std::filesystem::path& path);

/// Standard base64 with padding (data: URIs in glTF files written by the tests).
std::string base64(std::string_view bytes);
inline std::string base64(const std::vector<unsigned char>& bytes) {
  return base64(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace prt::test
