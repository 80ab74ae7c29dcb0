// Outputs of `prt render` beyond one file per frame: an H.264 video through ffmpeg and a
// contact sheet (a grid of downscaled frames in one PNG).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "prt/atomic_file.h"
#include "prt/image.h"

namespace prt::tools {

/// The absolute path of `program` found on $PATH, or "" when it is not there.
std::string findOnPath(const std::string& program);

/// Streams frames to ffmpeg (H.264, yuv420p, odd sizes padded to even with black), which writes
/// a temporary file next to `path`; finish() renames it over `path`. Destroyed unfinished (an
/// error), it stops ffmpeg and removes the temporary file.
class VideoEncoder {
 public:
  /// Throws prt::Error "--mp4 PATH: ffmpeg not found on PATH ..." when ffmpeg is missing. Does
  /// not touch `path` nor start ffmpeg yet (start()), so its folder may be created in between.
  explicit VideoEncoder(const std::string& path);
  ~VideoEncoder();
  VideoEncoder(const VideoEncoder&) = delete;
  VideoEncoder& operator=(const VideoEncoder&) = delete;

  /// Starts ffmpeg for frames of width × height at `fps` frames per second, writing to a
  /// temporary file next to the path. Throws prt::Error if the folder cannot be written.
  void start(int width, int height, double fps);
  /// Sends one frame (tone-mapped as prt::toneMapSrgb8). Throws prt::Error if ffmpeg failed.
  void addFrame(const ImageRgb& image, float exposure);
  /// Waits for ffmpeg, checks it succeeded, renames the file into place.
  void finish();
  const std::string& ffmpeg() const { return ffmpeg_; }

 private:
  [[noreturn]] void failWithLog(const std::string& what);
  void stop();
  std::string path_, ffmpeg_, logPath_;
  std::unique_ptr<AtomicFile> file_;
  int pipe_ = -1;
  int pid_ = -1;
  int width_ = 0, height_ = 0;
};

/// A grid of frames, each downscaled by an integer factor k (box filter over k × k pixels in
/// linear radiance; the last row and column of boxes may be partial), tiles in frame order,
/// row by row, 2 black pixels between tiles. Tone-mapped when written (same exposure as --png).
class ContactSheet {
 public:
  /// Sizes of a sheet, in 64 bits so that a caller can refuse one too large before making it.
  struct Layout {
    int64_t factor, tileWidth, tileHeight, columns, width, height;
  };
  /// The layout the constructor uses. Preconditions as for the constructor.
  static Layout layout(int64_t frameWidth, int64_t frameHeight, int64_t frames, int64_t columns, int64_t maxTile);
  /// k is the smallest integer with ceil(W/k) and ceil(H/k) <= maxTile; columns 0 = ceil(√frames).
  ContactSheet(int frameWidth, int frameHeight, int frames, int columns, int maxTile);
  /// Adds the next frame. Precondition: fewer than `frames` frames added, size as given.
  void add(const ImageRgb& frame);
  /// Writes the sheet as PNG, atomically.
  void write(const std::string& path, float exposure) const;

  int factor() const { return factor_; }
  int tileWidth() const { return tileWidth_; }
  int tileHeight() const { return tileHeight_; }
  int columns() const { return columns_; }
  const ImageRgb& image() const { return sheet_; }

  static constexpr int kGap = 2;

 private:
  int frameWidth_, frameHeight_, frames_, columns_, factor_, tileWidth_, tileHeight_;
  int added_ = 0;
  ImageRgb sheet_;
};

}  // namespace prt::tools
