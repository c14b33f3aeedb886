#pragma once
// Reading numbers from text strictly: the whole token, and finite. Used by
// the readers of our own (OBJ check, PLY, OFF) and the CLI's options, where
// `nan`, `1,5`, `0x10` or `3y` must be refused, not read as a prefix. And
// writing them as the shortest text that reads back exactly.

#include <charconv>
#include <cmath>
#include <string>
#include <string_view>

namespace curvenet::detail {

/// The whole token as a finite number (a leading '+' allowed).
inline bool parse_finite(std::string_view t, double& out) {
  if (!t.empty() && t.front() == '+')
    t.remove_prefix(1);
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), out, std::chars_format::general);
  return !t.empty() && ec == std::errc() && end == t.data() + t.size() && std::isfinite(out);
}

/// The whole token as an integer of type T (a leading '+' allowed).
template <class T> bool parse_whole(std::string_view t, T& out) {
  if (!t.empty() && t.front() == '+')
    t.remove_prefix(1);
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), out);
  return !t.empty() && ec == std::errc() && end == t.data() + t.size();
}

/// Appends a number as the shortest text that reads back to the same double
/// (std::to_chars; a few times faster than a stream at 17 digits, and as
/// exact).
inline void append_number(std::string& out, double v) {
  char text[32];
  out.append(text, std::to_chars(text, text + sizeof text, v).ptr);
}

inline void append_number(std::string& out, int v) {
  char text[16];
  out.append(text, std::to_chars(text, text + sizeof text, v).ptr);
}

} // namespace curvenet::detail
