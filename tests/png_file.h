// A minimal PNG encoder for tests (zlib "stored" blocks, no compression): images with exactly
// known texels, any colour type and bit depth, for the loader to decode.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace prt::test {

inline void appendBigEndian(std::string& s, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) s += char((v >> shift) & 0xFF);
}

inline uint32_t crc32(const std::string& bytes) {
  uint32_t crc = 0xFFFFFFFFu;
  for (unsigned char c : bytes) {
    crc ^= c;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

/// A PNG chunk: length, type, data, CRC.
inline std::string pngChunk(const std::string& type, const std::string& data) {
  std::string c;
  appendBigEndian(c, uint32_t(data.size()));
  c += type + data;
  appendBigEndian(c, crc32(type + data));
  return c;
}

/// A minimal PNG (zlib "stored" block, no compression), enough for stb to decode: `rows` holds
/// h rows of `rowBytes` bytes each, packed as the PNG colour type and bit depth say (16-bit
/// samples big-endian); `chunks` (PLTE, tRNS, ...) go before the image data.
inline std::string encodePngRaw(int w, int h, int bitDepth, int colorType, const std::vector<uint8_t>& rows,
                                size_t rowBytes, const std::string& chunks = "") {
  std::string raw;
  for (int y = 0; y < h; ++y) {
    raw += '\0';  // filter: none
    raw.append(reinterpret_cast<const char*>(rows.data()) + size_t(y) * rowBytes, rowBytes);
  }
  std::string z = "\x78\x01\x01";
  uint16_t len = uint16_t(raw.size());
  z += char(len & 0xFF);
  z += char(len >> 8);
  z += char(~len & 0xFF);
  z += char((~len >> 8) & 0xFF);
  z += raw;
  uint32_t a = 1, b = 0;
  for (unsigned char c : raw) {
    a = (a + c) % 65521;
    b = (b + a) % 65521;
  }
  appendBigEndian(z, (b << 16) | a);
  std::string ihdr;
  appendBigEndian(ihdr, uint32_t(w));
  appendBigEndian(ihdr, uint32_t(h));
  ihdr += char(bitDepth);
  ihdr += char(colorType);
  ihdr += std::string(3, '\0');  // deflate, adaptive filtering, no interlace
  return std::string("\x89PNG\r\n\x1a\n", 8) + pngChunk("IHDR", ihdr) + chunks + pngChunk("IDAT", z) +
         pngChunk("IEND", "");
}

/// An RGBA8 PNG.
inline std::string encodePng(int w, int h, const std::vector<uint8_t>& rgba) {
  return encodePngRaw(w, h, 8, 6, rgba, size_t(w) * 4);
}

}  // namespace prt::test
