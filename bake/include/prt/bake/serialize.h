// Plain-data serialisation for checkpoint records: a streamed 64-bit hash, and byte writers
// and readers of trivially copyable values and arrays.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace prt::bake {

/// 64-bit hash of bytes, streamed (for checksums and fingerprints; not cryptographic).
class Hasher {
 public:
  explicit Hasher(uint64_t seed = 0);
  void add(const void* data, size_t bytes);
  template <class T>
  void addVector(const std::vector<T>& v) {
    uint64_t n = v.size();
    add(&n, sizeof n);
    add(v.data(), v.size() * sizeof(T));
  }
  uint64_t digest() const;

 private:
  uint64_t h_;
  uint64_t tail_ = 0;
  int tailBytes_ = 0;
  uint64_t length_ = 0;
};

/// Appends plain data to a record payload.
class ByteWriter {
 public:
  virtual ~ByteWriter() = default;
  virtual void write(const void* data, size_t bytes) = 0;
  template <class T>
  void put(const T& v) {
    write(&v, sizeof v);
  }
  /// Writes count, then the elements (trivially copyable T).
  template <class T>
  void putArray(const T* data, size_t count) {
    put(uint64_t(count));
    write(data, count * sizeof(T));
  }
};

/// Reads a record payload back; throws prt::Error (naming the checkpoint) past its end.
class ByteReader {
 public:
  ByteReader(const std::string& data, std::string where) : data_(data), where_(std::move(where)) {}
  void read(void* out, size_t bytes);
  template <class T>
  T get() {
    T v;
    read(&v, sizeof v);
    return v;
  }
  /// Reads an array written by putArray into `out`, which must hold exactly `count` elements.
  template <class T>
  void getArray(T* out, size_t count) {
    uint64_t n = get<uint64_t>();
    if (n != count) fail("array size");
    read(out, count * sizeof(T));
  }
  /// Reads an array written by putArray, whatever its size (at most what the record holds).
  template <class T>
  std::vector<T> getVector() {
    uint64_t n = get<uint64_t>();
    if (n > (data_.size() - pos_) / sizeof(T)) fail("array size");
    std::vector<T> v(n);
    read(v.data(), n * sizeof(T));
    return v;
  }
  bool atEnd() const { return pos_ == data_.size(); }
  [[noreturn]] void fail(const std::string& what) const;

 private:
  const std::string& data_;
  size_t pos_ = 0;
  std::string where_;
};

}  // namespace prt::bake
