#include "prt/error.h"

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <utility>
#include <vector>

namespace prt {

namespace {
// The live CheckContext scopes of this thread, outermost first.
thread_local std::vector<const std::function<std::string()>*> checkContexts;
}  // namespace

CheckContext::CheckContext(std::function<std::string()> describe) : describe_(std::move(describe)) {
  checkContexts.push_back(&describe_);
}

CheckContext::~CheckContext() { checkContexts.pop_back(); }

namespace detail {
void checkFailed(const char* file, int line, const std::string& what) {
  std::fprintf(stderr, "prt: internal error at %s:%d: %s\n", file, line, what.c_str());
  // Taken off the thread first: a check that fails inside a description ends without context.
  const std::vector<const std::function<std::string()>*> contexts = std::move(checkContexts);
  checkContexts.clear();
  for (const std::function<std::string()>* describe : contexts) {
    std::string context;
    try {
      context = (*describe)();
    } catch (const std::exception& e) {
      context = cat("(its description failed: ", e.what(), ")");
    }
    std::fprintf(stderr, "prt:   while: %s\n", context.c_str());
  }
  std::abort();
}
}  // namespace detail

std::string printable(const std::string& s, size_t maxBytes) {
  std::string out;
  for (size_t i = 0; i < s.size();) {
    if (out.size() >= maxBytes) return out + "...";
    const auto c = static_cast<unsigned char>(s[i]);
    const size_t n = c < 0x80                 ? 1
                     : c >= 0xC2 && c <= 0xDF ? 2
                     : c >= 0xE0 && c <= 0xEF ? 3
                     : c >= 0xF0 && c <= 0xF4 ? 4
                                              : 0;
    bool valid = n > 0 && i + n <= s.size() && (n > 1 || (c >= 0x20 && c != 0x7F));
    for (size_t k = 1; valid && k < n; ++k) valid = (static_cast<unsigned char>(s[i + k]) & 0xC0) == 0x80;
    if (valid) {
      out.append(s, i, n);
      i += n;
    } else {
      const char* hex = "0123456789abcdef";
      out += {'\\', 'x', hex[c >> 4], hex[c & 15]};
      ++i;
    }
  }
  return out;
}

}  // namespace prt
