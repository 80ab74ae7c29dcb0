// HDR image I/O: OpenEXR and Radiance .hdr in, float32 OpenEXR and 8-bit sRGB PNG out.
#include "prt/image.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfThreading.h>
#include <stb_image.h>
#include <stb_image_write.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "prt/atomic_file.h"
#include "prt/error.h"

namespace prt {

namespace {

// Larger sides are refused before anything is allocated: a corrupt header cannot make us ask
// for gigabytes, and 32768 is far beyond any environment map or frame prt handles.
constexpr int64_t kMaxSide = 32768;
// And at most 2^27 pixels (16384 x 8192, the largest environment maps published): 1.5 GiB as
// float RGB, so a header alone cannot make us allocate tens of gigabytes.
constexpr int64_t kMaxPixels = int64_t(1) << 27;

enum class Format { Exr, Radiance, Unknown };

Format detectFormat(const std::string& data) {
  static const unsigned char kExrMagic[4] = {0x76, 0x2f, 0x31, 0x01};
  if (data.size() >= 4 && std::memcmp(data.data(), kExrMagic, 4) == 0) return Format::Exr;
  if (data.rfind("#?RADIANCE", 0) == 0 || data.rfind("#?RGBE", 0) == 0) return Format::Radiance;
  return Format::Unknown;
}

void checkDimensions(const std::string& path, int64_t w, int64_t h) {
  if (w <= 0 || h <= 0) throw Error(cat(path, ": image ", w, "x", h, " has no pixels"));
  if (w > kMaxSide || h > kMaxSide)
    throw Error(cat(path, ": image ", w, "x", h, " is too large (at most ", kMaxSide, " a side)"));
  if (w * h > kMaxPixels)
    throw Error(cat(path, ": image ", w, "x", h, " is too large (at most ", kMaxPixels, " pixels)"));
}

void checkFinite(const std::string& path, const ImageRgb& image) {
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const glm::vec3& p = image.at(x, y);
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw Error(cat(path, ": pixel (", x, ", ", y, ") is not finite"));
    }
}

// OpenEXR reads from the bytes already in memory, so the format we detected and the data we
// decode are the same file even if it changes on disk meanwhile.
class MemoryIStream : public Imf::IStream {
 public:
  MemoryIStream(const std::string& data, const std::string& path) : Imf::IStream(path.c_str()), data_(data) {}

  bool read(char c[], int n) override {
    if (n < 0 || pos_ > data_.size() || static_cast<uint64_t>(n) > data_.size() - pos_)
      throw std::runtime_error("unexpected end of file");
    std::memcpy(c, data_.data() + pos_, static_cast<size_t>(n));
    pos_ += static_cast<uint64_t>(n);
    return pos_ < data_.size();
  }
  uint64_t tellg() override { return pos_; }
  void seekg(uint64_t pos) override { pos_ = pos; }

 private:
  const std::string& data_;
  uint64_t pos_ = 0;
};

ImageRgb loadExr(const std::string& path, const std::string& data) {
  if (data.size() < 8) throw Error(cat(path, ": corrupt OpenEXR file (no version field)"));
  ImageRgb image;
  try {
    // The size is checked on the header alone, before InputFile allocates anything that
    // scales with it (line offset tables, then our pixels).
    {
      MemoryIStream stream(data, path);
      stream.seekg(8);  // past the magic number and the version field
      int version = 0;
      std::memcpy(&version, data.data() + 4, sizeof(version));  // little-endian, as is x86
      Imf::Header header;
      header.readFrom(stream, version);
      const Imath::Box2i dw = header.dataWindow();
      checkDimensions(path, int64_t(dw.max.x) - dw.min.x + 1, int64_t(dw.max.y) - dw.min.y + 1);
    }
    MemoryIStream stream(data, path);
    Imf::InputFile file(stream);
    const Imath::Box2i dw = file.header().dataWindow();
    const int64_t w = int64_t(dw.max.x) - dw.min.x + 1;
    const int64_t h = int64_t(dw.max.y) - dw.min.y + 1;
    checkDimensions(path, w, h);
    // Every chunk of pixels must be in the file before its pixels get memory: a header that
    // claims a large image over a few bytes is refused here, not after the allocation.
    if (!file.isComplete()) throw Error(cat(path, ": corrupt OpenEXR file (pixel data missing or truncated)"));

    const Imf::ChannelList& channels = file.header().channels();
    const bool rgb = channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B");
    if (!rgb && !channels.findChannel("Y")) {
      std::string names;
      for (auto it = channels.begin(); it != channels.end(); ++it) names += cat(names.empty() ? "" : ", ", it.name());
      throw Error(cat(path, ": no R, G, B or Y channels (found: ", names.empty() ? "none" : names, ")"));
    }
    const std::vector<const char*> used = rgb ? std::vector<const char*>{"R", "G", "B"} : std::vector<const char*>{"Y"};
    for (const char* name : used) {
      const Imf::Channel* c = channels.findChannel(name);
      if (c->xSampling != 1 || c->ySampling != 1)
        throw Error(cat(path, ": channel ", name, " is subsampled, which is not supported"));
    }

    image = ImageRgb(static_cast<int>(w), static_cast<int>(h));
    // Slices of FLOAT: OpenEXR converts HALF (and UINT) channels to float while reading.
    Imf::FrameBuffer fb;
    std::vector<float> luminance;
    if (rgb) {
      char* base = reinterpret_cast<char*>(image.pixels.data());
      const size_t xs = sizeof(glm::vec3), ys = xs * static_cast<size_t>(w);
      fb.insert("R", Imf::Slice::Make(Imf::FLOAT, base + 0 * sizeof(float), dw, xs, ys));
      fb.insert("G", Imf::Slice::Make(Imf::FLOAT, base + 1 * sizeof(float), dw, xs, ys));
      fb.insert("B", Imf::Slice::Make(Imf::FLOAT, base + 2 * sizeof(float), dw, xs, ys));
    } else {
      luminance.resize(image.pixels.size());
      fb.insert("Y", Imf::Slice::Make(Imf::FLOAT, luminance.data(), dw, sizeof(float),
                                      sizeof(float) * static_cast<size_t>(w)));
    }
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    for (size_t i = 0; i < luminance.size(); ++i) image.pixels[i] = glm::vec3(luminance[i]);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    // Iex::BaseExc derives from std::exception in OpenEXR 3; its message is one line.
    throw Error(cat(path, ": corrupt OpenEXR file (", e.what(), ")"));
  }
  return image;
}

// stb_image reads past the end of a .hdr file as zero bytes, which on run-length encoded scan
// lines means a run of length 0, forever: a truncated file would hang it. So first walk the
// pixel data exactly as stb_image will consume it, and report a file that ends too early.
// Returns false if the data ends before the last pixel; malformed runs are left to stb_image,
// which reports them itself.
bool radianceDataComplete(const std::string& data, int w, int h) {
  const size_t size = data.size();
  size_t pos = 0;
  // Header lines up to an empty one, then the resolution line (stb_image tokenises the same).
  for (bool blankSeen = false;;) {
    const size_t nl = data.find('\n', pos);
    if (nl == std::string::npos) return false;
    const bool blank = nl == pos;  // never the first line: it holds the magic "#?..."
    pos = nl + 1;
    if (blankSeen) break;
    blankSeen = blank;
  }
  auto byte = [&](size_t i) { return static_cast<unsigned char>(data[i]); };
  const uint64_t flatSize = 4ull * static_cast<uint64_t>(w) * static_cast<uint64_t>(h);
  if (w < 8 || w >= 32768) return size - pos >= flatSize;  // stb_image reads these flat
  for (int y = 0; y < h; ++y) {
    if (size - pos < 4) return false;
    // A scan line without the run-length marker makes stb_image restart and read the whole
    // image flat from here.
    if (byte(pos) != 2 || byte(pos + 1) != 2 || (byte(pos + 2) & 0x80)) return size - pos >= flatSize;
    if (((byte(pos + 2) << 8) | byte(pos + 3)) != w) return true;
    pos += 4;
    for (int channel = 0; channel < 4; ++channel)
      for (int x = 0; x < w;) {
        if (pos >= size) return false;
        int count = byte(pos++);
        if (count > 128) {  // a run: one value, count - 128 times
          if (pos >= size) return false;
          ++pos;
          count -= 128;
        } else if (size - pos < static_cast<size_t>(count)) {  // count literal values
          return false;
        } else {
          pos += static_cast<size_t>(count);
        }
        if (count > w - x) return true;
        x += count;
      }
  }
  return true;
}

ImageRgb loadRadiance(const std::string& path, const std::string& data) {
  if (data.size() > static_cast<size_t>(INT32_MAX)) throw Error(cat(path, ": file too large for a Radiance HDR image"));
  const auto* bytes = reinterpret_cast<const stbi_uc*>(data.data());
  const int len = static_cast<int>(data.size());
  int w = 0, h = 0, comp = 0;
  // Header first: the size is checked before stb_image allocates the pixels.
  if (!stbi_info_from_memory(bytes, len, &w, &h, &comp))
    throw Error(cat(path, ": corrupt Radiance HDR file (", stbi_failure_reason(), ")"));
  checkDimensions(path, w, h);
  if (!radianceDataComplete(data, w, h)) throw Error(cat(path, ": corrupt Radiance HDR file (pixel data ends early)"));
  std::unique_ptr<float, void (*)(void*)> pixels(stbi_loadf_from_memory(bytes, len, &w, &h, &comp, 3), stbi_image_free);
  if (!pixels) throw Error(cat(path, ": corrupt Radiance HDR file (", stbi_failure_reason(), ")"));
  ImageRgb image(w, h);
  std::memcpy(image.pixels.data(), pixels.get(), image.pixels.size() * sizeof(glm::vec3));
  return image;
}

void checkWritable(const std::string& path, const ImageRgb& image) {
  PRT_CHECK_EQ(image.pixels.size(), static_cast<size_t>(image.width) * image.height);
  if (image.width <= 0 || image.height <= 0)
    throw Error(cat(path, ": cannot write an image of ", image.width, "x", image.height, " pixels"));
}

}  // namespace

ImageRgb downsampleBox(const ImageRgb& image, int factor) {
  if (factor < 1 || image.width % factor != 0 || image.height % factor != 0)
    throw Error(cat("downsampleBox: a ", image.width, "x", image.height, " image cannot be averaged down by ", factor));
  ImageRgb out(image.width / factor, image.height / factor);
  const float weight = 1.0f / float(factor * factor);
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      glm::vec3 sum(0.0f);
      for (int j = 0; j < factor; ++j)
        for (int i = 0; i < factor; ++i) sum += image.at(factor * x + i, factor * y + j);
      out.at(x, y) = sum * weight;
    }
  return out;
}

ImageRgb loadHdrImage(const std::string& path) {
  const std::string data = readFile(path);
  ImageRgb image;
  switch (detectFormat(data)) {
    case Format::Exr:
      image = loadExr(path, data);
      break;
    case Format::Radiance:
      image = loadRadiance(path, data);
      break;
    case Format::Unknown:
      throw Error(cat(path, ": not an OpenEXR or Radiance HDR image"));
  }
  checkFinite(path, image);
  return image;
}

void writeExr(const std::string& path, const ImageRgb& image, ExrCompression compression) {
  // OpenEXR compresses blocks of lines on its own thread pool, which is empty by default: ZIP
  // at 1080p took 870 ms on one core, 500 ms on two (measured 2026-12-01).
  static std::once_flag threads;
  std::call_once(threads, [] { Imf::setGlobalThreadCount(int(std::max(1u, std::thread::hardware_concurrency()))); });
  checkWritable(path, image);
  AtomicFile out(path);
  try {
    Imf::Header header(image.width, image.height);
    // All three are lossless and deterministic. ZIP (the default) suits smooth renders and SH
    // reconstructions; it costs ~5x the write time of NONE for ~10% fewer bytes on renders.
    switch (compression) {
      case ExrCompression::None:
        header.compression() = Imf::NO_COMPRESSION;
        break;
      case ExrCompression::Zip:
        header.compression() = Imf::ZIP_COMPRESSION;
        break;
      case ExrCompression::Piz:
        header.compression() = Imf::PIZ_COMPRESSION;
        break;
    }
    for (const char* name : {"R", "G", "B"}) header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    // OpenEXR only reads through the frame buffer while writing; the cast does not mutate.
    char* base = const_cast<char*>(reinterpret_cast<const char*>(image.pixels.data()));
    const size_t xs = sizeof(glm::vec3), ys = xs * static_cast<size_t>(image.width);
    Imf::FrameBuffer fb;
    fb.insert("R", Imf::Slice(Imf::FLOAT, base + 0 * sizeof(float), xs, ys));
    fb.insert("G", Imf::Slice(Imf::FLOAT, base + 1 * sizeof(float), xs, ys));
    fb.insert("B", Imf::Slice(Imf::FLOAT, base + 2 * sizeof(float), xs, ys));
    Imf::OutputFile file(out.tempPath().c_str(), header);
    file.setFrameBuffer(fb);
    file.writePixels(image.height);
  } catch (const std::exception& e) {
    throw Error(cat(path, ": cannot write OpenEXR (", e.what(), ")"));
  }
  out.commit();
}

void writePng(const std::string& path, const ImageRgb& image, float exposure) {
  checkWritable(path, image);
  const std::vector<unsigned char> bytes = toneMapSrgb8(image, exposure);
  // stb's deflate effort: level 1 writes a 1080p frame ~20% faster than its default 8, for files
  // ~3% larger (measured 2026-12-01). The variable is stb's global; prt is its only user here.
  stbi_write_png_compression_level = 1;
  AtomicFile out(path);
  if (!stbi_write_png(out.tempPath().c_str(), image.width, image.height, 3, bytes.data(), image.width * 3))
    throw Error(cat(path, ": cannot write PNG"));
  out.commit();
}

// IEC 61966-2-1. The two pieces meet at 0.0031308 (linear) / 0.04045 (encoded).
float linearToSrgb(float v) {
  const double x = v;
  return static_cast<float>(x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055);
}

namespace {

int srgbCode(float v) { return int(std::lround(linearToSrgb(v) * 255.0f)); }

// threshold[k] (k = 1..255): the smallest float v in [0, 1] with srgbCode(v) >= k. srgbCode is
// monotone in v, and the bit patterns of non-negative floats order like their values, so a
// bisection over the patterns finds each threshold exactly. bucket[i]: the code of i / 4096,
// where a search for v in [i, i + 1) / 4096 starts (at most ~1 code per bucket: the steepest
// part of the curve, 255 · 12.92 per unit near 0, puts 0.8 codes in one).
struct SrgbTable {
  std::array<float, 256> threshold{};
  std::array<unsigned char, 4097> bucket{};
  SrgbTable() {
    auto fromBits = [](uint32_t b) {
      float f;
      std::memcpy(&f, &b, sizeof f);
      return f;
    };
    uint32_t one;
    const float oneF = 1.0f;
    std::memcpy(&one, &oneF, sizeof one);
    for (int k = 1; k < 256; ++k) {
      uint32_t lo = 0, hi = one;  // srgbCode(1) = 255 >= k
      while (lo < hi) {
        const uint32_t mid = lo + (hi - lo) / 2;
        if (srgbCode(fromBits(mid)) >= k)
          hi = mid;
        else
          lo = mid + 1;
      }
      threshold[size_t(k)] = fromBits(lo);
    }
    for (size_t i = 0; i < bucket.size(); ++i) bucket[i] = (unsigned char)srgbCode(float(i) / 4096.0f);
  }
};

const SrgbTable& srgbTable() {
  static const SrgbTable table;
  return table;
}

}  // namespace

unsigned char srgb8(float v) {
  v = v > 0.0f ? std::min(v, 1.0f) : 0.0f;  // also maps NaN to 0
  const SrgbTable& t = srgbTable();
  int code = t.bucket[size_t(v * 4096.0f)];
  while (code < 255 && t.threshold[size_t(code + 1)] <= v) ++code;
  return (unsigned char)code;
}

std::vector<unsigned char> toneMapSrgb8(const ImageRgb& image, float exposure) {
  const float scale = std::exp2(exposure);
  std::vector<unsigned char> bytes(image.pixels.size() * 3);
  srgbTable();  // built once, before the threads
  tbb::parallel_for(tbb::blocked_range<size_t>(0, image.pixels.size(), 16384),
                    [&](const tbb::blocked_range<size_t>& r) {
                      for (size_t i = r.begin(); i < r.end(); ++i)
                        for (int c = 0; c < 3; ++c) bytes[3 * i + size_t(c)] = srgb8(image.pixels[i][c] * scale);
                    });
  return bytes;
}

float srgbToLinear(float v) {
  const double x = v;
  return static_cast<float>(x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4));
}

}  // namespace prt
