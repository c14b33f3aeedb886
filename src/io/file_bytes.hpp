#pragma once
// A whole file's bytes, for the readers that parse from memory.

#include "curvenet/errors.hpp"

#include <fstream>
#include <sstream>
#include <string>

namespace curvenet::detail {

/// \throw InputError naming the file when it cannot be opened.
inline std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw InputError(path, "", "cannot open the file for reading");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

} // namespace curvenet::detail
