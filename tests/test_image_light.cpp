// Image I/O (OpenEXR, Radiance, PNG, sRGB) and light projection to SH.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

// stb (libstb, linked into the tests) writes .hdr files and decodes PNGs independently of prt.
#include <stb_image.h>
#include <stb_image_write.h>

#include "harness.h"
#include "prt/atomic_file.h"
#include "prt/error.h"
#include "prt/image.h"
#include "prt/light.h"
#include "prt/math.h"
#include "prt/sh.h"
#include "test_util.h"

namespace {

using prt::test::errorOf;

namespace fs = std::filesystem;
using prt::ExrCompression;
using prt::ImageRgb;

using prt::kPi;

// Float output: coefficients and pixels are stored as float, so comparisons against double
// references allow a few float ulps (2^-24 ≈ 6e-8) relative to the magnitudes involved.
constexpr double kFloatTol = 1e-6;

using prt::test::TempDir;

const std::string kEsplanade = prt::test::sourcePath("scenes/env/royal_esplanade_128.hdr");

void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// Every image error must start with the offending path, and say what is wrong.
void expectErrorAbout(const std::string& path, const std::string& phrase, const std::function<void()>& f) {
  const std::string msg = errorOf(f);
  EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
  EXPECT_NE(msg.find(phrase), std::string::npos) << msg;
}

// ---------------------------------------------------------------------------------------------
// A minimal OpenEXR writer (scan lines, no compression), so the tests can make files prt never
// writes itself: HALF channels, luminance only, an offset data window, absurd sizes.

struct ExrChannel {
  std::string name;
  int type;  // 1 = HALF, 2 = FLOAT (OpenEXR's PixelType)
  std::function<float(int x, int y)> value;
};

template <class T>
void put(std::string& s, T v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof(v));  // little-endian, as is x86
}

void putAttribute(std::string& s, const std::string& name, const std::string& type, const std::string& value) {
  s += name;
  s += '\0';
  s += type;
  s += '\0';
  put<int32_t>(s, static_cast<int32_t>(value.size()));
  s += value;
}

// Exactly representable halves only (the test values are chosen so).
uint16_t toHalf(float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  if ((b & 0x7fffffffu) == 0) return static_cast<uint16_t>(b >> 16);
  const uint32_t sign = (b >> 16) & 0x8000u;
  const int exponent = static_cast<int>((b >> 23) & 0xff) - 127 + 15;
  EXPECT_TRUE(exponent > 0 && exponent < 31 && (b & 0x1fffu) == 0) << f << " is not a half";
  return static_cast<uint16_t>(sign | (exponent << 10) | ((b >> 13) & 0x3ffu));
}

// Channels must be given in alphabetical order, as OpenEXR stores them.
std::string makeExr(int xMin, int yMin, int xMax, int yMax, const std::vector<ExrChannel>& channels) {
  std::string s;
  put<uint32_t>(s, 20000630u);  // magic 0x76 0x2f 0x31 0x01
  put<int32_t>(s, 2);           // version 2, single part scan lines
  std::string list;
  for (const auto& c : channels) {
    list += c.name;
    list += '\0';
    put<int32_t>(list, c.type);
    put<uint32_t>(list, 0);  // pLinear + reserved
    put<int32_t>(list, 1);
    put<int32_t>(list, 1);
  }
  list += '\0';
  putAttribute(s, "channels", "chlist", list);
  putAttribute(s, "compression", "compression", std::string(1, '\0'));
  std::string box;
  for (int v : {xMin, yMin, xMax, yMax}) put<int32_t>(box, v);
  putAttribute(s, "dataWindow", "box2i", box);
  putAttribute(s, "displayWindow", "box2i", box);
  putAttribute(s, "lineOrder", "lineOrder", std::string(1, '\0'));
  std::string one, centre;
  put<float>(one, 1.0f);
  put<float>(centre, 0.0f);
  put<float>(centre, 0.0f);
  putAttribute(s, "pixelAspectRatio", "float", one);
  putAttribute(s, "screenWindowCenter", "v2f", centre);
  putAttribute(s, "screenWindowWidth", "float", one);
  s += '\0';
  if (xMax < xMin || yMax < yMin || xMax - xMin > 1000 || yMax - yMin > 1000) return s;

  std::vector<std::string> lines;
  for (int y = yMin; y <= yMax; ++y) {
    std::string data;
    for (const auto& c : channels)
      for (int x = xMin; x <= xMax; ++x) {
        if (c.type == 1)
          put<uint16_t>(data, toHalf(c.value(x, y)));
        else
          put<float>(data, c.value(x, y));
      }
    std::string line;
    put<int32_t>(line, y);
    put<int32_t>(line, static_cast<int32_t>(data.size()));
    lines.push_back(line + data);
  }
  uint64_t offset = s.size() + 8 * lines.size();
  for (const auto& line : lines) {
    put<uint64_t>(s, offset);
    offset += line.size();
  }
  for (const auto& line : lines) s += line;
  return s;
}

// ---------------------------------------------------------------------------------------------
// Image I/O

ImageRgb testImage(int w, int h) {
  ImageRgb img(w, h);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-3.0f, 50.0f);
  for (auto& p : img.pixels) p = glm::vec3(u(rng), u(rng), u(rng));
  // Values half floats could not hold, to prove the file is float32.
  img.at(0, 0) = glm::vec3(0.1f, 1e-30f, 3.0e38f);
  img.at(1, 0) = glm::vec3(1.0f + 1.0f / 4096.0f, -7e-5f, 65536.5f);
  return img;
}

TEST(ImageExr, WriteReadRoundTripIsExact) {
  TempDir dir;
  const std::string path = dir.file("round.exr");
  const ImageRgb img = testImage(13, 7);
  prt::writeExr(path, img);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"round.exr"}) << "temporary file left";
  const ImageRgb back = prt::loadHdrImage(path);
  ASSERT_EQ(back.width, 13);
  ASSERT_EQ(back.height, 7);
  for (int y = 0; y < 7; ++y)
    for (int x = 0; x < 13; ++x) EXPECT_EQ(back.at(x, y), img.at(x, y)) << x << ", " << y;
}

// Every compression prt offers is lossless: random floats (incompressible, with values half
// floats cannot hold) and a smooth gradient come back bit for bit. The smooth image shows the
// option took effect: ZIP stores it in well under half the bytes of NONE.
TEST(ImageExr, EveryCompressionIsLossless) {
  TempDir dir;
  ImageRgb smooth(64, 32);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 64; ++x) smooth.at(x, y) = glm::vec3(0.5f, float(x) / 64.0f, float(y) / 32.0f);
  std::map<std::string, uintmax_t> smoothBytes;
  for (auto [name, c] : {std::pair{"none", ExrCompression::None}, std::pair{"zip", ExrCompression::Zip},
                         std::pair{"piz", ExrCompression::Piz}}) {
    for (const ImageRgb& img : {testImage(13, 7), smooth}) {
      const std::string path = dir.file(std::string(name) + ".exr");
      prt::writeExr(path, img, c);
      const ImageRgb back = prt::loadHdrImage(path);
      ASSERT_EQ(back.width, img.width) << name;
      ASSERT_EQ(back.height, img.height) << name;
      EXPECT_TRUE(back.pixels == img.pixels) << name;
      smoothBytes[name] = std::filesystem::file_size(path);  // the smooth image is written last
    }
  }
  EXPECT_LT(2 * smoothBytes["zip"], smoothBytes["none"]);
  EXPECT_LT(2 * smoothBytes["piz"], smoothBytes["none"]);
}

TEST(ImageExr, OverwritesAtomically) {
  TempDir dir;
  const std::string path = dir.file("a.exr");
  prt::writeExr(path, testImage(4, 3));
  ImageRgb second(2, 2);
  second.at(1, 1) = glm::vec3(5.0f);
  prt::writeExr(path, second);
  const ImageRgb back = prt::loadHdrImage(path);
  ASSERT_EQ(back.width, 2);
  EXPECT_EQ(back.at(1, 1), glm::vec3(5.0f));
  EXPECT_EQ(dir.entries().size(), 1u);
}

TEST(ImageExr, ReadsHalfChannelsWithOffsetDataWindow) {
  TempDir dir;
  const std::string path = dir.file("half.exr");
  // A data window that does not start at (0, 0): row 0 of the image is the window's top row.
  auto r = [](int x, int y) { return 0.5f * float(x) + 0.25f * float(y); };
  auto g = [](int x, int y) { return -1.5f + float(x * y); };
  auto b = [](int, int y) { return 1024.0f + float(y); };
  writeBytes(path, makeExr(3, -2, 6, 0, {{"B", 1, b}, {"G", 1, g}, {"R", 1, r}}));
  const ImageRgb img = prt::loadHdrImage(path);
  ASSERT_EQ(img.width, 4);
  ASSERT_EQ(img.height, 3);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 4; ++x) EXPECT_EQ(img.at(x, y), glm::vec3(r(x + 3, y - 2), g(x + 3, y - 2), b(x + 3, y - 2)));
}

TEST(ImageExr, ReadsLuminanceOnlyAsGrey) {
  TempDir dir;
  const std::string path = dir.file("y.exr");
  auto lum = [](int x, int y) { return 0.1f * float(x) + float(y); };
  writeBytes(path, makeExr(0, 0, 4, 1, {{"Y", 2, lum}}));
  const ImageRgb img = prt::loadHdrImage(path);
  ASSERT_EQ(img.width, 5);
  ASSERT_EQ(img.height, 2);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 5; ++x) EXPECT_EQ(img.at(x, y), glm::vec3(lum(x, y)));
}

// The bundled 128 x 64 copy of the Poly Haven map (scenes/README.md): run-length encoded scan
// lines, as the 1k original that this test read before the suite kept to the repository.
TEST(ImageHdr, ReadsRoyalEsplanade) {
  const std::string path = kEsplanade;
  const ImageRgb img = prt::loadHdrImage(path);
  ASSERT_EQ(img.width, 128);
  ASSERT_EQ(img.height, 64);
  ASSERT_EQ(img.pixels.size(), 128u * 64u);
  glm::dvec3 sum(0.0);
  for (const auto& p : img.pixels) {
    ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
    ASSERT_TRUE(p.x >= 0.0f && p.y >= 0.0f && p.z >= 0.0f);  // RGBE cannot hold negatives
    sum += glm::dvec3(p);
  }
  const glm::dvec3 mean = sum / double(img.pixels.size());
  EXPECT_GT(mean.x, 0.0);
  EXPECT_GT(mean.y, 0.0);
  EXPECT_GT(mean.z, 0.0);
  // An outdoor map in daylight: the sky above is brighter than the ground below (the top and
  // bottom quarters of the rows, 128 of 512 in the 1k original).
  glm::dvec3 top(0.0), bottom(0.0);
  for (int x = 0; x < img.width; ++x)
    for (int y = 0; y < img.height / 4; ++y) {
      top += glm::dvec3(img.at(x, y));
      bottom += glm::dvec3(img.at(x, img.height - 1 - y));
    }
  EXPECT_GT(top.y, bottom.y);
}

TEST(ImageHdr, ReadsWhatStbWrites) {
  TempDir dir;
  // 20 wide: stb writes run-length encoded scan lines (8 <= width < 32768), prt's reader walks
  // them before decoding.
  const std::string path = dir.file("small.hdr");
  const int w = 20, h = 3;
  std::vector<float> data(w * h * 3);
  for (size_t i = 0; i < data.size(); ++i) data[i] = 0.013f * float(i * i) + 0.001f;
  ASSERT_TRUE(stbi_write_hdr(path.c_str(), w, h, 3, data.data()));
  const ImageRgb img = prt::loadHdrImage(path);
  ASSERT_EQ(img.width, w);
  ASSERT_EQ(img.height, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float* p = &data[(y * w + x) * 3];
      // RGBE: 8-bit mantissas under one shared exponent 2^e with max(r, g, b) in
      // [2^(e-1), 2^e); the writer truncates, so each channel loses less than 2^e / 256,
      // i.e. less than max(r, g, b) / 128.
      const float tol = std::max({p[0], p[1], p[2]}) / 128.0f;
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(img.at(x, y)[c], p[c], tol) << x << ", " << y;
    }
}

TEST(ImageErrors, MissingFile) {
  TempDir dir;
  const std::string path = dir.file("nope.exr");
  expectErrorAbout(path, "no such file", [&] { prt::loadHdrImage(path); });
}

TEST(ImageErrors, GarbageAndEmptyFiles) {
  TempDir dir;
  const std::string garbage = dir.file("garbage.exr"), empty = dir.file("empty.hdr");
  writeBytes(garbage, "this is not an image at all\n");
  writeBytes(empty, "");
  expectErrorAbout(garbage, "not an OpenEXR or Radiance HDR image", [&] { prt::loadHdrImage(garbage); });
  expectErrorAbout(empty, "not an OpenEXR or Radiance HDR image", [&] { prt::loadHdrImage(empty); });
}

TEST(ImageErrors, TruncatedExr) {
  TempDir dir;
  const std::string good = dir.file("good.exr");
  prt::writeExr(good, testImage(64, 32));
  const std::string bytes = prt::readFile(good);
  // Cut inside the pixel data, inside the header, and just after the magic number.
  for (size_t keep : {bytes.size() - 10, bytes.size() / 2, size_t(40), size_t(6)}) {
    const std::string path = dir.file(prt::cat("cut", keep, ".exr"));
    writeBytes(path, bytes.substr(0, keep));
    expectErrorAbout(path, "corrupt OpenEXR file", [&] { prt::loadHdrImage(path); });
  }
  // The same for an uncompressed file, whose scan lines are read as they are.
  const std::string plain = makeExr(0, 0, 7, 7,
                                    {{"B", 2, [](int, int) { return 1.0f; }},
                                     {"G", 2, [](int, int) { return 1.0f; }},
                                     {"R", 2, [](int, int) { return 1.0f; }}});
  const std::string path = dir.file("cut_plain.exr");
  writeBytes(path, plain.substr(0, plain.size() - 50));
  expectErrorAbout(path, "corrupt OpenEXR file", [&] { prt::loadHdrImage(path); });
}

TEST(ImageErrors, TruncatedHdr) {
  // stb_image alone would read zeros past the end (and hang on run-length data).
  TempDir dir;
  const std::string bytes = prt::readFile(kEsplanade);  // 29 KB of run-length encoded scan lines
  for (size_t keep : {bytes.size() - 1, bytes.size() / 3, size_t(120)}) {
    const std::string path = dir.file(prt::cat("cut", keep, ".hdr"));
    writeBytes(path, bytes.substr(0, keep));
    expectErrorAbout(path, "corrupt Radiance HDR file", [&] { prt::loadHdrImage(path); });
  }
  const std::string flat = dir.file("flat.hdr");  // 4 pixels wide: stored flat, 64 bytes
  writeBytes(flat, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 4\nabc");
  expectErrorAbout(flat, "pixel data ends early", [&] { prt::loadHdrImage(flat); });
}

TEST(ImageErrors, ZeroAndAbsurdSizes) {
  TempDir dir;
  auto one = [](int, int) { return 1.0f; };
  const std::string empty = dir.file("empty_window.exr");
  writeBytes(empty, makeExr(0, 0, -1, 4, {{"Y", 2, one}}));
  expectErrorAbout(empty, "image 0x5", [&] { prt::loadHdrImage(empty); });

  // Refused from the header alone: the file has no pixel data at all.
  const std::string huge = dir.file("huge.exr");
  writeBytes(huge, makeExr(0, 0, 99999, 9, {{"Y", 2, one}}));
  expectErrorAbout(huge, "image 100000x10 is too large", [&] { prt::loadHdrImage(huge); });

  const std::string hdrZero = dir.file("zero.hdr");
  writeBytes(hdrZero, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 0 +X 0\n");
  expectErrorAbout(hdrZero, "image 0x0 has no pixels", [&] { prt::loadHdrImage(hdrZero); });

  const std::string hdrHuge = dir.file("huge.hdr");
  writeBytes(hdrHuge, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 40000\n");
  expectErrorAbout(hdrHuge, "image 40000x4 is too large", [&] { prt::loadHdrImage(hdrHuge); });
}

TEST(ImageErrors, NoColourChannels) {
  TempDir dir;
  const std::string path = dir.file("depth.exr");
  writeBytes(path, makeExr(0, 0, 1, 1, {{"Z", 2, [](int, int) { return 1.0f; }}}));
  expectErrorAbout(path, "no R, G, B or Y channels (found: Z)", [&] { prt::loadHdrImage(path); });
}

TEST(ImageErrors, NonFinitePixel) {
  TempDir dir;
  const std::string path = dir.file("nan.exr");
  ImageRgb img(6, 4);
  img.at(4, 2).y = std::numeric_limits<float>::quiet_NaN();
  img.at(5, 3).x = std::numeric_limits<float>::infinity();
  prt::writeExr(path, img);
  expectErrorAbout(path, "pixel (4, 2) is not finite", [&] { prt::loadHdrImage(path); });
}

TEST(ImageErrors, WriteToMissingDirectoryLeavesNothing) {
  TempDir dir;
  const std::string path = dir.file("missing/out.exr");
  expectErrorAbout(path, "does not exist", [&] { prt::writeExr(path, testImage(4, 4)); });
  const std::string png = dir.file("missing/out.png");
  expectErrorAbout(png, "does not exist", [&] { prt::writePng(png, testImage(4, 4)); });
  EXPECT_TRUE(dir.entries().empty());
}

TEST(ImageErrors, EmptyImageIsNotWritten) {
  TempDir dir;
  const std::string path = dir.file("empty.exr");
  expectErrorAbout(path, "0x0", [&] { prt::writeExr(path, ImageRgb()); });
  EXPECT_TRUE(dir.entries().empty());
}

// The sRGB encoding written out independently of prt, from IEC 61966-2-1.
double srgbEncode(double v) { return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055; }

TEST(ImagePng, WritesClampedSrgbBytes) {
  TempDir dir;
  const std::vector<float> values = {0.0f, 0.001f, 0.01f, 0.18f, 0.5f,
                                     0.9f, 1.0f,   2.0f,  -0.3f, std::numeric_limits<float>::quiet_NaN()};
  ImageRgb img(static_cast<int>(values.size()), 2);
  for (int x = 0; x < img.width; ++x) {
    img.at(x, 0) = glm::vec3(values[x], values[x] * 0.5f, values[x] * 0.25f);
    img.at(x, 1) = glm::vec3(values[x]);
  }
  for (float exposure : {0.0f, -1.0f, 1.5f}) {
    const std::string path = dir.file(prt::cat("out", exposure, ".png"));
    prt::writePng(path, img, exposure);
    int w = 0, h = 0, comp = 0;
    unsigned char* data = stbi_load(path.c_str(), &w, &h, &comp, 0);
    ASSERT_NE(data, nullptr) << stbi_failure_reason();
    ASSERT_EQ(w, img.width);
    ASSERT_EQ(h, 2);
    ASSERT_EQ(comp, 3);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) {
          double v = double(img.at(x, y)[c]) * std::exp2(double(exposure));
          v = std::isnan(v) ? 0.0 : std::clamp(v, 0.0, 1.0);
          const double expected = std::round(srgbEncode(v) * 255.0);
          // Float evaluation of the curve may land on the other side of a .5 boundary.
          EXPECT_NEAR(data[(y * w + x) * 3 + c], expected, 1.0)
              << "x " << x << " y " << y << " c " << c << " exposure " << exposure;
          if (v == 0.0 || v == 1.0) {
            EXPECT_EQ(data[(y * w + x) * 3 + c], expected);
          }
        }
    stbi_image_free(data);
  }
  // Spot values: linear 0.5 is sRGB 0.7354 -> 188; 0.18 -> 0.4614 -> 118.
  int w = 0, h = 0, comp = 0;
  unsigned char* data = stbi_load(dir.file("out0.png").c_str(), &w, &h, &comp, 3);
  ASSERT_NE(data, nullptr);
  EXPECT_EQ(data[(w + 4) * 3], 188);
  EXPECT_EQ(data[(w + 3) * 3], 118);
  EXPECT_EQ(data[(w + 7) * 3], 255);
  EXPECT_EQ(data[(w + 8) * 3], 0);
  stbi_image_free(data);
}

TEST(ImageSrgb, CurvesAreExactAndInverse) {
  for (double v : {0.0, 0.001, 0.0031308, 0.004, 0.05, 0.18, 0.5, 0.999, 1.0})
    EXPECT_NEAR(prt::linearToSrgb(float(v)), srgbEncode(v), kFloatTol) << v;
  EXPECT_NEAR(prt::linearToSrgb(0.5f), 0.735356983, kFloatTol);
  EXPECT_NEAR(prt::srgbToLinear(0.5f), 0.214041140, kFloatTol);
  EXPECT_NEAR(prt::srgbToLinear(0.04045f), 0.04045 / 12.92, kFloatTol);
  float previous = -1.0f;
  for (int i = 0; i <= 1000; ++i) {
    const float v = float(i) / 1000.0f;
    const float e = prt::linearToSrgb(v);
    EXPECT_GT(e, previous);
    previous = e;
    EXPECT_NEAR(prt::srgbToLinear(e), v, kFloatTol) << v;
  }
}

// ---------------------------------------------------------------------------------------------
// Equirectangular mapping

void expectDir(const glm::dvec3& a, const glm::dvec3& b) {
  EXPECT_NEAR(a.x, b.x, 1e-12);
  EXPECT_NEAR(a.y, b.y, 1e-12);
  EXPECT_NEAR(a.z, b.z, 1e-12);
}

// srgb8 reads a table instead of calling pow: it must give exactly lround(linearToSrgb(v)·255)
// for every v, so it is checked at every threshold between two codes (the last float below it
// and the threshold itself), on random values, and on the clamped ones.
TEST(ImageSrgb8, EqualsRoundedTransferFunctionExactly) {
  auto reference = [](float v) {
    v = v > 0.0f ? std::min(v, 1.0f) : 0.0f;
    return int(std::lround(prt::linearToSrgb(v) * 255.0f));
  };
  float v = 0.0f;
  for (int k = 1; k < 256; ++k) {
    // Step up to the first float whose code is k (bisection over the bit patterns), then check
    // it and its neighbours.
    uint32_t lo, hi;
    std::memcpy(&lo, &v, 4);
    const float one = 1.0f;
    std::memcpy(&hi, &one, 4);
    while (lo < hi) {
      const uint32_t mid = lo + (hi - lo) / 2;
      float m;
      std::memcpy(&m, &mid, 4);
      if (reference(m) >= k)
        hi = mid;
      else
        lo = mid + 1;
    }
    std::memcpy(&v, &lo, 4);
    ASSERT_EQ(reference(v), k);  // the bisection found the threshold: the codes step by one
    for (float x : {std::nextafter(v, 0.0f), v, std::nextafter(v, 2.0f)})
      EXPECT_EQ(int(prt::srgb8(x)), reference(x)) << x;
  }
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int i = 0; i < 200000; ++i) {
    const float x = i % 2 ? u(rng) : u(rng) * u(rng) * u(rng);  // many near 0, where codes are dense
    ASSERT_EQ(int(prt::srgb8(x)), reference(x)) << x;
  }
  for (float x : {-1.0f, -0.0f, 0.0f, 1.0f, 1.5f, 1e30f, std::numeric_limits<float>::infinity(),
                  std::numeric_limits<float>::quiet_NaN()})
    EXPECT_EQ(int(prt::srgb8(x)), reference(x)) << x;
}

TEST(LightEquirect, Orientation) {
  expectDir(prt::equirectDirection(0.5, 0.5), {1, 0, 0});
  expectDir(prt::equirectDirection(0.75, 0.5), {0, 0, 1});
  expectDir(prt::equirectDirection(0.25, 0.5), {0, 0, -1});
  expectDir(prt::equirectDirection(0.0, 0.5), {-1, 0, 0});
  expectDir(prt::equirectDirection(1.0, 0.5), {-1, 0, 0});
  for (double u : {0.0, 0.3, 0.9}) {
    expectDir(prt::equirectDirection(u, 0.0), {0, 1, 0});
    expectDir(prt::equirectDirection(u, 1.0), {0, -1, 0});
  }
  // Half way up, looking along +X: 45° above the horizon.
  expectDir(prt::equirectDirection(0.5, 0.25), {std::sqrt(0.5), std::sqrt(0.5), 0});
  const glm::dvec2 top = prt::equirectUv({0, 1, 0});
  EXPECT_NEAR(top.y, 0.0, 1e-12);
  const glm::dvec2 z = prt::equirectUv({0, 0, 1});
  EXPECT_NEAR(z.x, 0.75, 1e-12);
  EXPECT_NEAR(z.y, 0.5, 1e-12);
}

TEST(LightEquirect, RoundTrip) {
  for (int i = 1; i < 40; ++i)
    for (int j = 1; j < 20; ++j) {
      const double u = i / 40.0, v = j / 20.0;
      const glm::dvec3 d = prt::equirectDirection(u, v);
      EXPECT_NEAR(glm::length(d), 1.0, 1e-14);
      const glm::dvec2 uv = prt::equirectUv(d);
      EXPECT_NEAR(uv.x, u, 1e-12);
      EXPECT_NEAR(uv.y, v, 1e-12);
    }
  std::mt19937 rng(3);
  std::normal_distribution<double> n;
  for (int i = 0; i < 200; ++i) {
    const glm::dvec3 d = glm::normalize(glm::dvec3(n(rng), n(rng), n(rng)));
    const glm::dvec2 uv = prt::equirectUv(d);
    EXPECT_TRUE(uv.x >= 0.0 && uv.x <= 1.0 && uv.y >= 0.0 && uv.y <= 1.0);
    expectDir(prt::equirectDirection(uv.x, uv.y), d);
  }
}

TEST(LightEquirect, SampleIsBilinearBetweenPixelCentresWrappingInU) {
  prt::ImageRgb m(4, 3);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 4; ++x) m.at(x, y) = glm::vec3(float(x + 10 * y), float(y), 1.0f);
  auto at = [&](double u, double v) { return prt::sampleEquirect(m, prt::equirectDirection(u, v)); };
  auto near = [](const glm::dvec3& a, const glm::dvec3& b) { return glm::length(a - b) < 1e-9; };
  // At a pixel centre: the pixel.
  EXPECT_TRUE(near(at(1.5 / 4, 1.5 / 3), glm::dvec3(11, 1, 1)));
  // Halfway between two centres in u and in v: their means.
  EXPECT_TRUE(near(at(2.0 / 4, 1.5 / 3), glm::dvec3(11.5, 1, 1)));
  EXPECT_TRUE(near(at(1.5 / 4, 1.0 / 3), glm::dvec3(6, 0.5, 1)));
  // Across the seam: between the last column and the first.
  EXPECT_TRUE(near(at(0.01 / 4, 1.5 / 3), glm::dvec3(0.49 * 13 + 0.51 * 10, 1, 1)));
  // Above the first row's centres and below the last's: clamped to the row.
  EXPECT_TRUE(near(at(1.5 / 4, 0.1 / 3), glm::dvec3(1, 0, 1)));
  EXPECT_TRUE(near(at(1.5 / 4, 2.9 / 3), glm::dvec3(21, 2, 1)));
}

// ---------------------------------------------------------------------------------------------
// Environment projection

// Pixel-centre direction of (x, row), written out here rather than through equirectDirection.
glm::dvec3 pixelCentre(int x, int row, int w, int h) {
  const double theta = kPi * (row + 0.5) / h;
  const double phi = 2.0 * kPi * ((x + 0.5) / w - 0.5);
  return {std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)};
}

ImageRgb mapOf(int w, int h, const std::function<glm::dvec3(const glm::dvec3&)>& f) {
  ImageRgb img(w, h);
  for (int row = 0; row < h; ++row)
    for (int x = 0; x < w; ++x) img.at(x, row) = glm::vec3(f(pixelCentre(x, row, w, h)));
  return img;
}

// Quadrature error of the projection. In φ the pixel centres are a W-point midpoint rule,
// exact for the trigonometric polynomials of degree < W that products of band-limited
// functions with y_i are (degree <= 14 here, W >= 64). In θ each row holds its exact solid
// angle times the value at the row's centre θ_c. Expanding F(θ) = ∫ f y_i dφ about θ_c, row by
// row, the error of ∫ F sin θ dθ sums to
//   (Δθ² / 24) · (c_i - F(0) - F(π)) + O(Δθ⁴),   F(0) = 2π f(+Y) y_i(+Y), F(π) likewise,
// with Δθ = π/H (that is exact - quadrature; the test below checks the formula itself). The
// tolerance takes that term with a factor 2 for the O(Δθ⁴) remainder, plus
// float rounding of the stored coefficients.
double quadratureTol(int h, double c, double poleTerms) {
  const double dTheta = kPi / h;
  return 2.0 * dTheta * dTheta / 24.0 * (std::abs(c) + poleTerms) + kFloatTol * (1 + std::abs(c));
}

void expectProjection(const std::function<glm::dvec3(const glm::dvec3&)>& f, const std::vector<glm::dvec3>& expected,
                      int w, int h, int bands) {
  const prt::sh::ShRgb c = prt::projectEnvironment(mapOf(w, h, f), bands);
  ASSERT_EQ(c.bands, bands);
  double yUp[64], yDown[64];
  prt::sh::evaluate(bands, glm::dvec3(0, 1, 0), yUp);
  prt::sh::evaluate(bands, glm::dvec3(0, -1, 0), yDown);
  const glm::dvec3 fUp = f({0, 1, 0}), fDown = f({0, -1, 0});
  for (int i = 0; i < c.size(); ++i) {
    const glm::dvec3 want = i < int(expected.size()) ? expected[i] : glm::dvec3(0.0);
    for (int ch = 0; ch < 3; ++ch) {
      const double poles = 2 * kPi * (std::abs(fUp[ch] * yUp[i]) + std::abs(fDown[ch] * yDown[i]));
      EXPECT_NEAR(c.c[i][ch], want[ch], quadratureTol(h, want[ch], poles))
          << "coefficient " << i << " channel " << ch << " map " << w << "x" << h;
    }
  }
}

TEST(LightEnvironment, ConstantMap) {
  const double c0 = 2.0 * std::sqrt(kPi);
  const glm::dvec3 radiance(1.0, 2.0, 0.25);
  expectProjection([](const glm::dvec3&) { return glm::dvec3(1.0); }, {glm::dvec3(c0)}, 64, 32, 8);
  expectProjection([&](const glm::dvec3&) { return radiance; }, {c0 * radiance}, 128, 64, 3);
  // The solid angles sum to 4π exactly, so c_0 is exact to rounding at any resolution.
  const prt::sh::ShRgb c = prt::projectEnvironment(mapOf(6, 3, [](auto&) { return glm::dvec3(1); }), 1);
  EXPECT_NEAR(c.c[0].x, c0, kFloatTol * c0);
}

TEST(LightEnvironment, BandLimitedFunction) {
  // y_1..y_8 in closed form (prt/sh.h): y_3 = k1 x, y_5 = k2 yz, y_8 = k3 (x² - y²), y_2 = k1 z,
  // y_1 = k1 y, y_4 = k2 xy, y_6 = k4 (3z² - 1).
  const double k0 = 0.5 / std::sqrt(kPi), k1 = std::sqrt(3.0 / (4.0 * kPi));
  const double k2 = std::sqrt(15.0 / (4.0 * kPi)), k3 = std::sqrt(15.0 / (16.0 * kPi));
  const double k4 = std::sqrt(5.0 / (16.0 * kPi));
  auto f = [](const glm::dvec3& d) {
    return glm::dvec3(1.0 + 0.5 * d.x + 0.3 * d.z * d.y + 0.2 * (d.x * d.x - d.y * d.y),
                      0.7 - 0.4 * d.z + 0.25 * d.x * d.y, 0.2 + 0.1 * d.y + 0.6 * d.z * d.z);
  };
  std::vector<glm::dvec3> want(9, glm::dvec3(0.0));
  // Constants: 1 = y_0 / k0. z² = (y_6 / k4 + 1) / 3.
  want[0] = glm::dvec3(1.0 / k0, 0.7 / k0, (0.2 + 0.6 / 3.0) / k0);
  want[1] = glm::dvec3(0.0, 0.0, 0.1 / k1);
  want[2] = glm::dvec3(0.0, -0.4 / k1, 0.0);
  want[3] = glm::dvec3(0.5 / k1, 0.0, 0.0);
  want[4] = glm::dvec3(0.0, 0.25 / k2, 0.0);
  want[5] = glm::dvec3(0.3 / k2, 0.0, 0.0);
  want[6] = glm::dvec3(0.0, 0.0, 0.6 / (3.0 * k4));
  want[8] = glm::dvec3(0.2 / k3, 0.0, 0.0);
  expectProjection(f, want, 128, 64, 8);
  expectProjection(f, want, 512, 256, 4);
}

TEST(LightEnvironment, QuadratureErrorIsTheExpectedSecondOrderTerm) {
  // f = y² = (1 + band 2) / 3, so c_0 = 2√π / 3, and F(0) = F(π) = 2π · 1 · y_0. The error
  // formula above predicts quad - exact = (Δθ²/24)(4π y_0 - c_0) = (Δθ²/24)(4√π/3): check the
  // value, and its fourfold drop when H doubles. Weights sin θ_c · Δθ instead of the exact
  // solid angles, or a map flipped upside down, would give other errors.
  const double exact = 2.0 * std::sqrt(kPi) / 3.0;
  auto err = [&](int h) {
    const prt::sh::ShRgb p =
        prt::projectEnvironment(mapOf(2 * h, h, [](const glm::dvec3& d) { return glm::dvec3(d.y * d.y); }), 3);
    return double(p.c[0].x) - exact;
  };
  for (int h : {16, 32, 64}) {
    const double dTheta = kPi / h;
    const double predicted = dTheta * dTheta / 24.0 * 4.0 * std::sqrt(kPi) / 3.0;
    // The O(Δθ⁴) remainder is below 2% of the leading term from H = 16 on.
    EXPECT_NEAR(err(h), predicted, 0.02 * predicted + kFloatTol) << "H " << h;
  }
}

TEST(LightEnvironment, SinglePixelIsItsSolidAngleTimesValue) {
  const int w = 32, h = 16, bands = 8;
  for (auto [px, row] : {std::pair{23, 5}, std::pair{0, 0}, std::pair{8, 15}, std::pair{16, 8}}) {
    ImageRgb img(w, h);
    const glm::dvec3 value(2.0, 3.0, 40.0);
    img.at(px, row) = glm::vec3(value);
    const prt::sh::ShRgb c = prt::projectEnvironment(img, bands);
    const double omega = (2.0 * kPi / w) * (std::cos(kPi * row / h) - std::cos(kPi * (row + 1) / h));
    double y[64];
    prt::sh::evaluate(bands, pixelCentre(px, row, w, h), y);
    for (int i = 0; i < c.size(); ++i)
      for (int ch = 0; ch < 3; ++ch) {
        const double want = omega * value[ch] * y[i];
        EXPECT_NEAR(c.c[i][ch], want, kFloatTol * omega * value[ch]) << i << " " << px << "," << row;
      }
  }
}

TEST(LightEnvironment, DeterministicWhateverTheThreads) {
  ImageRgb img(512, 256);
  std::mt19937 rng(11);
  std::exponential_distribution<float> e(0.5f);
  for (auto& p : img.pixels) p = glm::vec3(e(rng), e(rng), e(rng));
  prt::sh::ShRgb one;
  {
    tbb::global_control serial(tbb::global_control::max_allowed_parallelism, 1);
    one = prt::projectEnvironment(img, 8);
  }
  const prt::sh::ShRgb many = prt::projectEnvironment(img, 8);
  const prt::sh::ShRgb again = prt::projectEnvironment(img, 8);
  for (int i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one.c[i], many.c[i]) << i;
    EXPECT_EQ(many.c[i], again.c[i]) << i;
  }
}

TEST(LightEnvironment, RoyalEsplanadeIrradianceIsPlausible) {
  const ImageRgb img = prt::loadHdrImage(kEsplanade);
  const prt::sh::ShRgb c = prt::projectEnvironment(img, 3);
  // c_0 is the mean radiance times 2√π; the pixel-weighted mean must agree with it.
  glm::dvec3 weighted(0.0);
  for (int row = 0; row < img.height; ++row) {
    const double omega =
        (2.0 * kPi / img.width) * (std::cos(kPi * row / img.height) - std::cos(kPi * (row + 1) / img.height));
    for (int x = 0; x < img.width; ++x) weighted += omega * glm::dvec3(img.at(x, row));
  }
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(c.c[0][ch], weighted[ch] / (2.0 * std::sqrt(kPi)), 1e-5 * weighted[ch]);
  const glm::vec3 up = prt::sh::irradiance(c, {0, 1, 0}), down = prt::sh::irradiance(c, {0, -1, 0});
  EXPECT_GT(up.y, down.y);
  EXPECT_GT(down.y, 0.0f);
}

TEST(LightEnvironment, RejectsBadInput) {
  EXPECT_THROW(prt::projectEnvironment(ImageRgb(), 3), prt::Error);
  EXPECT_THROW(prt::projectEnvironment(ImageRgb(4, 2), 0), prt::Error);
  EXPECT_THROW(prt::projectEnvironment(ImageRgb(4, 2), 9), prt::Error);
}

// ---------------------------------------------------------------------------------------------
// Disks and suns

// Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_n), for the brute-force cap
// integrals below: n nodes integrate polynomials of degree < 2n exactly.
void gaussLegendre(int n, std::vector<double>& x, std::vector<double>& w) {
  x.resize(n);
  w.resize(n);
  for (int i = 0; i < n; ++i) {
    double t = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 0.0;
    for (int iter = 0; iter < 100; ++iter) {
      double p0 = 1.0, p1 = t;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * t * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (t * p1 - p0) / (t * t - 1.0);
      const double dt = p1 / dp;
      t -= dt;
      if (std::abs(dt) < 1e-16) break;
    }
    x[i] = t;
    w[i] = 2.0 / ((1.0 - t * t) * dp * dp);
  }
}

// ∫_cap y_i(ω) dω over the cap of radius r about d, by direct quadrature in the cap's own
// frame: ω = cos α d + sin α (cos β t₁ + sin β t₂), dω = d(cos α) dβ. Averaged over β, y_i
// restricted to the cap is a polynomial of degree <= 7 in cos α, so 16 Gauss-Legendre nodes in
// cos α ∈ [cos r, 1] and 32 uniform β are exact up to rounding.
std::vector<double> capIntegrals(int bands, const glm::dvec3& d, double r) {
  std::vector<double> gx, gw;
  gaussLegendre(16, gx, gw);
  const glm::dvec3 t1 = glm::normalize(glm::cross(d, std::abs(d.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0)));
  const glm::dvec3 t2 = glm::cross(d, t1);
  const double lo = std::cos(r);
  const int nBeta = 32;
  std::vector<double> out(bands * bands, 0.0);
  double y[64];
  for (int i = 0; i < 16; ++i) {
    const double ca = lo + (1.0 - lo) * 0.5 * (gx[i] + 1.0);
    const double wa = (1.0 - lo) * 0.5 * gw[i];
    const double sa = std::sqrt(std::max(0.0, 1.0 - ca * ca));
    for (int j = 0; j < nBeta; ++j) {
      const double b = 2.0 * kPi * (j + 0.5) / nBeta;
      const glm::dvec3 w = ca * d + sa * (std::cos(b) * t1 + std::sin(b) * t2);
      prt::sh::evaluate(bands, glm::normalize(w), y);
      for (int k = 0; k < bands * bands; ++k) out[k] += wa * (2.0 * kPi / nBeta) * y[k];
    }
  }
  return out;
}

TEST(LightDisk, MatchesBruteForceCapIntegral) {
  const glm::dvec3 d = glm::normalize(glm::dvec3(0.3, 0.8, -0.5));
  const glm::dvec3 radiance(1.0, 0.5, 7.0);
  for (int bands : {1, 3, 8})
    for (double r : {0.01, 0.05, 0.3, 1.0, kPi / 2, 2.5, kPi}) {
      const prt::sh::ShRgb c = prt::projectDiskRadiance(bands, d, r, radiance);
      ASSERT_EQ(c.bands, bands);
      const std::vector<double> ref = capIntegrals(bands, d, r);
      // |c_i| <= L · Ω · max|y_i| with Ω the cap's solid angle and max|y_i| < 1.5 for l < 8, so
      // float rounding of the coefficients stays below kFloatTol · L · Ω.
      const double omega = 2.0 * kPi * (1.0 - std::cos(r));
      for (int i = 0; i < c.size(); ++i)
        for (int ch = 0; ch < 3; ++ch)
          EXPECT_NEAR(c.c[i][ch], radiance[ch] * ref[i], kFloatTol * radiance[ch] * omega)
              << "bands " << bands << " r " << r << " i " << i;
    }
}

TEST(LightDisk, WholeSphereIsUniform) {
  const prt::sh::ShRgb disk = prt::projectDiskRadiance(8, {0, 0, 1}, kPi, glm::dvec3(1.5));
  const prt::sh::ShRgb uniform = prt::projectUniform(8, glm::dvec3(1.5));
  for (int i = 0; i < disk.size(); ++i)
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(disk.c[i][ch], uniform.c[i][ch], 1e-5) << i;
}

TEST(LightDisk, RejectsBadInput) {
  const glm::dvec3 up(0, 1, 0), one(1.0);
  EXPECT_THROW(prt::projectDiskRadiance(3, up, 0.0, one), prt::Error);
  EXPECT_THROW(prt::projectDiskRadiance(3, up, -0.1, one), prt::Error);
  EXPECT_THROW(prt::projectDiskRadiance(3, up, 3.2, one), prt::Error);
  EXPECT_THROW(prt::projectDiskRadiance(3, up, std::nan(""), one), prt::Error);
  EXPECT_THROW(prt::projectDiskRadiance(3, glm::dvec3(0.0), 0.1, one), prt::Error);
  EXPECT_THROW(prt::projectDiskRadiance(9, up, 0.1, one), prt::Error);
}

TEST(LightSun, LowBandsAreExactForAnyRadius) {
  // With L = E / (π sin² r) on the cap (a surface facing the sun receives E):
  //   c_00 = ∫_cap L y_0 dω = y_0 · L · 2π (1 - cos r) = y_0 · E · 2 / (1 + cos r),
  //   c_1m = ∫_cap L y_1m dω = √(3/4π) · L · ∫_cap ω dω = √(3/4π) · L · π sin² r · d
  //        = E · y_1m(d).
  // So band 1 carries exactly the vector irradiance E·d for every radius, and band 0 the
  // total flux ∫ L dω, which exceeds E (the cos θ of a surface facing the disk is < 1 off axis).
  const glm::dvec3 d = glm::normalize(glm::dvec3(-0.2, 0.4, 0.9));
  const glm::dvec3 e(3.0, 2.0, 1.0);
  const double y0 = 0.5 / std::sqrt(kPi), k1 = std::sqrt(3.0 / (4.0 * kPi));
  for (double r : {0.0, 1e-6, 0.0046, 0.1, 0.7, 1.5}) {
    const prt::sh::ShRgb c = prt::projectSun(3, d, r, e);
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_NEAR(c.c[0][ch], y0 * e[ch] * 2.0 / (1.0 + std::cos(r)), kFloatTol * e[ch]) << r;
      EXPECT_NEAR(c.c[1][ch], k1 * d.y * e[ch], kFloatTol * e[ch]) << r;
      EXPECT_NEAR(c.c[2][ch], k1 * d.z * e[ch], kFloatTol * e[ch]) << r;
      EXPECT_NEAR(c.c[3][ch], k1 * d.x * e[ch], kFloatTol * e[ch]) << r;
    }
  }
}

TEST(LightSun, IsTheDiskOfMatchingRadiance) {
  const glm::dvec3 d(0, 0, -1), e(5.0, 4.0, 3.0);
  for (double r : {0.01, 0.2, 1.2}) {
    const prt::sh::ShRgb sun = prt::projectSun(8, d, r, e);
    const prt::sh::ShRgb disk = prt::projectDiskRadiance(8, d, r, e / (kPi * std::sin(r) * std::sin(r)));
    for (int i = 0; i < sun.size(); ++i)
      for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(sun.c[i][ch], disk.c[i][ch], 1e-5 * e[ch]) << r << " " << i;
  }
}

TEST(LightSun, SmallRadiusTendsToTheDelta) {
  const glm::dvec3 d = glm::normalize(glm::dvec3(1.0, 2.0, -0.5)), e(1.0, 10.0, 0.1);
  double y[64];
  prt::sh::evaluate(8, d, y);
  const prt::sh::ShRgb delta = prt::projectSun(8, d, 0.0, e);
  for (int i = 0; i < delta.size(); ++i)
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(delta.c[i][ch], e[ch] * y[i], kFloatTol * e[ch]);
  // Band l of a sun of radius r is E y_lm(d) (1 + r²/4 - l(l+1) r²/8 + O(r⁴)) (expand
  // 2 ∫_{cos r}^1 P_l / sin² r in s = 1 - cos r): allow twice that. Radii down to 1e-9 check
  // that no precision is lost where 1 - cos r underflows in double.
  for (double r : {1e-2, 1e-4, 1e-9}) {
    const prt::sh::ShRgb c = prt::projectSun(8, d, r, e);
    for (int i = 0; i < c.size(); ++i) {
      const int l = prt::sh::bandOf(i);
      for (int ch = 0; ch < 3; ++ch) {
        const double want = e[ch] * y[i];
        const double tol = 2.0 * (0.25 + l * (l + 1) / 8.0) * r * r * std::abs(want) + kFloatTol * e[ch];
        EXPECT_NEAR(c.c[i][ch], want, tol) << "r " << r << " i " << i;
      }
    }
  }
}

TEST(LightSun, ThreeBandIrradianceOfADeltaOvershootsBy17Over16) {
  // A delta sun truncated to 3 bands, seen by a surface facing it: Σ_l Â_l Σ_m E y_lm(d)²
  // = E Σ_l Â_l (2l+1)/(4π) = E (π·1 + (2π/3)·3 + (π/4)·5) / (4π) = E · 17/16 (not E: the
  // exact value needs every band). A misplaced π in the sun or in Â_l breaks this equality.
  const glm::dvec3 d = glm::normalize(glm::dvec3(0.3, -0.2, 0.9));
  const prt::sh::ShRgb c = prt::projectSun(3, d, 0.0, glm::dvec3(16.0, 1.0, 0.0));
  const glm::vec3 e = prt::sh::irradiance(c, glm::vec3(d));
  EXPECT_NEAR(e.x, 17.0, 1e-4);
  EXPECT_NEAR(e.y, 17.0 / 16.0, 1e-5);
  EXPECT_EQ(e.z, 0.0f);
}

TEST(LightSun, RejectsBadRadiusAndDirection) {
  const glm::dvec3 up(0, 1, 0), one(1.0);
  EXPECT_NO_THROW(prt::projectSun(3, up, 0.0, one));
  EXPECT_THROW(prt::projectSun(3, up, kPi / 2, one), prt::Error);
  EXPECT_THROW(prt::projectSun(3, up, -1e-3, one), prt::Error);
  EXPECT_THROW(prt::projectSun(3, up, std::nan(""), one), prt::Error);
  EXPECT_THROW(prt::projectSun(3, glm::dvec3(0.0), 0.01, one), prt::Error);
}

TEST(LightUniform, UnitRadianceGivesIrradiancePi) {
  // A white sky of radiance 1 gives E = ∫_hemisphere cos θ dω = π at every normal.
  const prt::sh::ShRgb c = prt::projectUniform(3, glm::dvec3(1.0));
  EXPECT_NEAR(c.c[0].x, 2.0 * std::sqrt(kPi), kFloatTol);
  for (int i = 1; i < c.size(); ++i) EXPECT_EQ(c.c[i], glm::vec3(0.0f));
  for (const glm::vec3 n : {glm::vec3(0, 1, 0), glm::vec3(0, -1, 0), glm::vec3(1, 0, 0)}) {
    const glm::vec3 e = prt::sh::irradiance(c, n);
    EXPECT_NEAR(e.x, kPi, 1e-5);
    EXPECT_NEAR(e.z, kPi, 1e-5);
  }
  // The same through an environment map of radiance 1 (c_0 exact, the rest within quadrature).
  const prt::sh::ShRgb m = prt::projectEnvironment(ImageRgb(64, 32), 3);
  EXPECT_EQ(m.c[0], glm::vec3(0.0f));
  ImageRgb white(64, 32);
  for (auto& p : white.pixels) p = glm::vec3(1.0f);
  // Band 2 picks up the quadrature error (Δθ²/24) · 2π (y_i(+Y) + y_i(-Y)) per coefficient
  // (see quadratureTol); at N = +Y that adds (π/4)(Δθ²/24) · 4π Σ_m y_2m(+Y)² = (5π/96) Δθ².
  const double dTheta = kPi / 32;
  EXPECT_NEAR(prt::sh::irradiance(prt::projectEnvironment(white, 3), {0, 1, 0}).y,
              kPi + 5.0 * kPi / 96.0 * dTheta * dTheta, 1e-5);
}

}  // namespace
