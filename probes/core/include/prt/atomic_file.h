// Outputs are written to a temporary file beside the target and renamed over it, so the output
// path only ever holds nothing, the previous good file, or the new complete one.
#pragma once

#include <string>

namespace prt {

class AtomicFile {
 public:
  /// Prepares a temporary path next to `path` (same directory, so rename is atomic).
  /// Throws prt::Error if the directory does not exist or is not writable.
  explicit AtomicFile(std::string path);
  ~AtomicFile();  // removes the temporary file unless commit() succeeded
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  /// Where to write.
  const std::string& tempPath() const { return temp_; }
  const std::string& path() const { return path_; }
  /// fsyncs the temporary file and renames it over path(). Throws prt::Error on failure.
  void commit();

 private:
  std::string path_;
  std::string temp_;
  bool committed_ = false;
};

/// Writes `data` to `path` atomically.
void writeFileAtomic(const std::string& path, const std::string& data);

/// Reads a whole file; throws prt::Error "PATH: cannot read (reason)".
std::string readFile(const std::string& path);

}  // namespace prt
