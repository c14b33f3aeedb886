#pragma once
// The names an error message quotes ('like this'), in order: which
// profiles, rings or nodes a failure is about.

#include <string>
#include <vector>

namespace curvenet::detail {

inline std::vector<std::string> quoted(const std::string& text) {
  std::vector<std::string> out;
  for (size_t at = text.find('\''); at != std::string::npos;) {
    const size_t end = text.find('\'', at + 1);
    if (end == std::string::npos)
      break;
    if (end > at + 1)
      out.push_back(text.substr(at + 1, end - at - 1));
    at = text.find('\'', end + 1);
  }
  return out;
}

} // namespace curvenet::detail
