#include "frame_outputs.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string_view>

#include "prt/error.h"

extern char** environ;

namespace prt::tools {

std::string findOnPath(const std::string& program) {
  const char* env = std::getenv("PATH");
  if (!env) return "";
  const std::string_view all(env);
  for (size_t start = 0; start <= all.size();) {
    size_t end = std::min(all.find(':', start), all.size());
    // An empty entry means the current folder (POSIX).
    const std::filesystem::path dir = end > start ? std::filesystem::path(all.substr(start, end - start)) : ".";
    const std::string candidate = (dir / program).string();
    struct stat st {};
    if (::stat(candidate.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(candidate.c_str(), X_OK) == 0)
      return candidate;
    start = end + 1;
  }
  return "";
}

// ---------------------------------------------------------------------------------------------
// Video

VideoEncoder::VideoEncoder(const std::string& path) : path_(path) {
  ffmpeg_ = findOnPath("ffmpeg");
  if (ffmpeg_.empty()) throw Error(cat("--mp4 ", path, ": ffmpeg not found on PATH (install ffmpeg, or drop --mp4)"));
}

VideoEncoder::~VideoEncoder() {
  stop();
  if (!logPath_.empty()) ::unlink(logPath_.c_str());
}

void VideoEncoder::stop() {
  if (pipe_ >= 0) ::close(pipe_);
  pipe_ = -1;
  if (pid_ > 0) {
    ::kill(pid_, SIGTERM);
    int status = 0;
    while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {}
  }
  pid_ = -1;
}

void VideoEncoder::start(int width, int height, double fps) {
  file_ = std::make_unique<AtomicFile>(path_);  // a missing or read-only folder fails here
  width_ = width;
  height_ = height;
  // ffmpeg's messages go to a log file, shown (last line) only if it fails.
  char logName[] = "/tmp/prt-ffmpeg-XXXXXX";
  int logFd = ::mkstemp(logName);
  if (logFd < 0) throw Error(cat(path_, ": cannot create a log file for ffmpeg: ", std::strerror(errno)));
  logPath_ = logName;
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    ::close(logFd);
    throw Error(cat(path_, ": cannot create a pipe to ffmpeg: ", std::strerror(errno)));
  }
  // yuv420p (what players expect) needs even sizes: pad odd ones with a black row/column.
  std::vector<std::string> args = {ffmpeg_,
                                   "-nostdin",
                                   "-hide_banner",
                                   "-loglevel",
                                   "error",
                                   "-y",
                                   "-f",
                                   "rawvideo",
                                   "-pix_fmt",
                                   "rgb24",
                                   "-s",
                                   cat(width, "x", height),
                                   "-framerate",
                                   cat(fps),
                                   "-i",
                                   "pipe:0",
                                   "-vf",
                                   "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                                   "-c:v",
                                   "libx264",
                                   "-crf",
                                   "18",
                                   "-pix_fmt",
                                   "yuv420p",
                                   "-movflags",
                                   "+faststart",
                                   "-f",
                                   "mp4",
                                   file_->tempPath()};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[0], 0);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, logFd, 2);
  pid_t pid = -1;
  int rc = ::posix_spawn(&pid, ffmpeg_.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(fds[0]);
  ::close(logFd);
  if (rc != 0) {
    ::close(fds[1]);
    throw Error(cat(path_, ": cannot start ", ffmpeg_, ": ", std::strerror(rc)));
  }
  pid_ = pid;
  pipe_ = fds[1];
  // A write to a pipe whose reader died raises SIGPIPE, which would kill prt without a word;
  // ignored, the write fails with EPIPE and the error names ffmpeg's last message instead.
  ::signal(SIGPIPE, SIG_IGN);
}

void VideoEncoder::failWithLog(const std::string& what) {
  stop();
  std::ifstream log(logPath_);
  std::string line, last;
  while (std::getline(log, line))
    if (!line.empty()) last = line;
  throw Error(cat(path_, ": ", what, last.empty() ? "" : ": ", last));
}

void VideoEncoder::addFrame(const ImageRgb& image, float exposure) {
  PRT_CHECK(pipe_ >= 0);
  PRT_CHECK(image.width == width_ && image.height == height_);
  std::vector<unsigned char> bytes = prt::toneMapSrgb8(image, exposure);
  size_t done = 0;
  while (done < bytes.size()) {
    ssize_t n = ::write(pipe_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) failWithLog(cat("ffmpeg stopped reading frames (", std::strerror(errno), ")"));
    done += size_t(n);
  }
}

void VideoEncoder::finish() {
  PRT_CHECK(pipe_ >= 0);
  ::close(pipe_);
  pipe_ = -1;
  int status = 0;
  while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {}
  pid_ = -1;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    failWithLog(WIFEXITED(status) ? cat("ffmpeg failed (exit status ", WEXITSTATUS(status), ")")
                                  : std::string("ffmpeg was killed"));
  file_->commit();
}

// ---------------------------------------------------------------------------------------------
// Contact sheet

ContactSheet::Layout ContactSheet::layout(int64_t frameWidth, int64_t frameHeight, int64_t frames, int64_t columns,
                                          int64_t maxTile) {
  PRT_CHECK(frameWidth > 0 && frameHeight > 0 && frames > 0 && maxTile > 0 && columns >= 0);
  Layout l{};
  const int64_t longest = std::max(frameWidth, frameHeight);
  l.factor = (longest + maxTile - 1) / maxTile;  // smallest k with ceil(longest / k) <= maxTile
  l.tileWidth = (frameWidth + l.factor - 1) / l.factor;
  l.tileHeight = (frameHeight + l.factor - 1) / l.factor;
  l.columns = columns > 0 ? std::min(columns, frames) : int64_t(std::ceil(std::sqrt(double(frames)) - 1e-9));
  const int64_t rows = (frames + l.columns - 1) / l.columns;
  l.width = l.columns * (l.tileWidth + kGap) - kGap;
  l.height = rows * (l.tileHeight + kGap) - kGap;
  return l;
}

ContactSheet::ContactSheet(int frameWidth, int frameHeight, int frames, int columns, int maxTile)
    : frameWidth_(frameWidth), frameHeight_(frameHeight), frames_(frames) {
  const Layout l = layout(frameWidth, frameHeight, frames, columns, maxTile);
  PRT_CHECK(l.width <= std::numeric_limits<int>::max() / l.height);
  factor_ = int(l.factor);
  tileWidth_ = int(l.tileWidth);
  tileHeight_ = int(l.tileHeight);
  columns_ = int(l.columns);
  sheet_ = ImageRgb(int(l.width), int(l.height));
}

void ContactSheet::add(const ImageRgb& frame) {
  PRT_CHECK(added_ < frames_);
  PRT_CHECK(frame.width == frameWidth_ && frame.height == frameHeight_);
  const int x0 = (added_ % columns_) * (tileWidth_ + kGap), y0 = (added_ / columns_) * (tileHeight_ + kGap);
  const int k = factor_;
  for (int ty = 0; ty < tileHeight_; ++ty)
    for (int tx = 0; tx < tileWidth_; ++tx) {
      // The box of frame pixels this tile pixel covers; at the right and bottom edges it may be
      // cut by the frame's border, and the mean is over the pixels that exist.
      const int xe = std::min((tx + 1) * k, frameWidth_), ye = std::min((ty + 1) * k, frameHeight_);
      glm::dvec3 sum(0.0);
      for (int y = ty * k; y < ye; ++y)
        for (int x = tx * k; x < xe; ++x) sum += glm::dvec3(frame.at(x, y));
      sheet_.at(x0 + tx, y0 + ty) = glm::vec3(sum / double((xe - tx * k) * (ye - ty * k)));
    }
  ++added_;
}

void ContactSheet::write(const std::string& path, float exposure) const { writePng(path, sheet_, exposure); }

}  // namespace prt::tools
