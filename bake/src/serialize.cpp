#include "prt/bake/serialize.h"

#include <cstring>

#include "prt/error.h"

namespace prt::bake {

namespace {

inline uint64_t rotl(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }
constexpr uint64_t kP1 = 0x9E3779B185EBCA87ull, kP2 = 0xC2B2AE3D27D4EB4Full;

}  // namespace

// ---- Hasher: 64-bit words mixed xxHash-style; enough to catch torn writes and edits.
Hasher::Hasher(uint64_t seed) : h_(seed ^ kP1) {}

void Hasher::add(const void* data, size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  length_ += bytes;
  while (bytes > 0 && tailBytes_ != 0) {
    tail_ |= uint64_t(*p++) << (8 * tailBytes_);
    --bytes;
    if (++tailBytes_ == 8) {
      h_ = rotl(h_ ^ (tail_ * kP2), 31) * kP1;
      tail_ = 0;
      tailBytes_ = 0;
    }
  }
  for (; bytes >= 8; bytes -= 8, p += 8) {
    uint64_t w;
    std::memcpy(&w, p, 8);
    h_ = rotl(h_ ^ (w * kP2), 31) * kP1;
  }
  // Here bytes < 8, and the tail is empty unless bytes is 0.
  for (size_t i = 0; i < bytes; ++i) tail_ |= uint64_t(p[i]) << (8 * i);
  if (bytes > 0) tailBytes_ = int(bytes);
}

uint64_t Hasher::digest() const {
  uint64_t h = h_ ^ (tail_ * kP2) ^ length_;
  h ^= h >> 33;
  h *= kP2;
  h ^= h >> 29;
  h *= kP1;
  return h ^ (h >> 32);
}

void ByteReader::read(void* out, size_t bytes) {
  if (bytes > data_.size() - pos_) fail("record shorter than its contents");
  if (bytes > 0) std::memcpy(out, data_.data() + pos_, bytes);  // out may be null when empty
  pos_ += bytes;
}

void ByteReader::fail(const std::string& what) const {
  throw Error(cat(where_, ": corrupt checkpoint (", what, "); delete it to start over"));
}

}  // namespace prt::bake
