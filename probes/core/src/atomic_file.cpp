#include "prt/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "prt/error.h"

namespace prt {

namespace fs = std::filesystem;

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  if (path_.empty()) throw Error("output path is empty");
  fs::path p(path_);
  fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw Error(cat(path_, ": cannot write: directory '", dir.string(), "' does not exist"));
  if (fs::is_directory(p, ec)) throw Error(cat(path_, ": cannot write: is a directory"));
  // A unique name in the same directory: pid + counter, hidden, with the final extension kept
  // last so libraries that pick a format by extension still see it.
  static int counter = 0;
  std::string stem = p.filename().string();
  std::string ext = p.extension().string();
  temp_ = (dir / cat(".", stem, ".tmp", ::getpid(), "-", counter++, ext)).string();
  if (::access(dir.c_str(), W_OK) != 0) throw Error(cat(path_, ": cannot write: ", std::strerror(errno)));
}

AtomicFile::~AtomicFile() {
  if (!committed_) ::unlink(temp_.c_str());
}

void AtomicFile::commit() {
  int fd = ::open(temp_.c_str(), O_RDONLY);
  if (fd < 0) throw Error(cat(path_, ": cannot write: temporary file missing (", std::strerror(errno), ")"));
  ::fsync(fd);
  ::close(fd);
  if (std::rename(temp_.c_str(), path_.c_str()) != 0) throw Error(cat(path_, ": cannot write: ", std::strerror(errno)));
  committed_ = true;
}

void writeFileAtomic(const std::string& path, const std::string& data) {
  AtomicFile file(path);
  {
    std::ofstream out(file.tempPath(), std::ios::binary);
    if (!out) throw Error(cat(path, ": cannot write: ", std::strerror(errno)));
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
    out.flush();
    if (!out) throw Error(cat(path, ": cannot write: ", std::strerror(errno)));
  }
  file.commit();
}

std::string readFile(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(cat(path, ": no such file"));
  if (fs::is_directory(path, ec)) throw Error(cat(path, ": is a directory, expected a file"));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(cat(path, ": cannot read: ", std::strerror(errno)));
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw Error(cat(path, ": cannot read: I/O error"));
  return ss.str();
}

}  // namespace prt
