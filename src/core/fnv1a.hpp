#pragma once
// FNV-1a, 64 bits: the fingerprint of binding caches, farm manifests and
// frame part files (a check against damage and mix-ups, not a secure hash).

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace curvenet::detail {

struct Fnv1a {
  std::uint64_t value = 1469598103934665603ULL;
  void eat(const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < n; ++i)
      value = (value ^ p[i]) * 1099511628211ULL;
  }
  void eat(std::string_view s) { eat(s.data(), s.size()); }
};

inline std::uint64_t fnv1a(std::string_view s) {
  Fnv1a h;
  h.eat(s);
  return h.value;
}

} // namespace curvenet::detail
