#include "io/obj_check.hpp"

#include "core/numbers.hpp"
#include "curvenet/errors.hpp"

#include <charconv>
#include <cmath>
#include <sstream>
#include <string_view>
#include <vector>

namespace curvenet::detail {
namespace {

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

std::vector<std::string_view> tokens(std::string_view line) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i]))
      ++i;
    size_t j = i;
    while (j < line.size() && !is_space(line[j]))
      ++j;
    if (j > i)
      out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

} // namespace

ObjCounts check_obj(const std::string& path, const std::string& bytes) {
  std::istringstream in(bytes);
  ObjCounts n;
  // A positive index may refer to an element further down the file; it is
  // checked at the end, against the line of the largest one.
  long long largest[3] = {0, 0, 0}, largest_line[3] = {0, 0, 0};
  std::string largest_corner[3];
  std::string line;
  long long first_line = 0;
  auto fail = [&](const std::string& what) { throw InputError(path, "line " + std::to_string(first_line), what); };
  // (No line continuations: tinyobjloader does not join lines either.)
  while (std::getline(in, line)) {
    ++first_line;
    const std::string_view whole = line;
    const std::string_view text = whole.substr(0, std::min(whole.find('#'), whole.size()));
    const auto t = tokens(text);
    if (!t.empty()) {
      const std::string_view key = t[0];
      auto coordinates = [&](size_t least, size_t most, const char* what) {
        if (t.size() - 1 < least)
          fail(std::string(what) + " has " + std::to_string(t.size() - 1) + " coordinates, needs " +
               std::to_string(least));
        for (size_t k = 1; k < t.size() && k <= most; ++k) {
          double x = 0;
          if (!parse_finite(t[k], x))
            fail(std::string(what) + " coordinate '" + std::string(t[k]) + "' is not a finite number");
        }
      };
      if (key == "v") {
        coordinates(3, 7, "vertex");
        ++n.positions;
      } else if (key == "vt") {
        coordinates(1, 3, "texture coordinate");
        ++n.texcoords;
      } else if (key == "vn") {
        coordinates(3, 3, "normal");
        ++n.normals;
      } else if (key == "f") {
        if (t.size() - 1 < 3)
          fail("face has " + std::to_string(t.size() - 1) + " corners, needs at least 3");
        for (size_t k = 1; k < t.size(); ++k) {
          // v, v/vt, v//vn or v/vt/vn
          std::string_view c = t[k];
          std::string_view part[3];
          int parts = 0;
          while (parts < 3) {
            const size_t slash = c.find('/');
            part[parts++] = c.substr(0, slash);
            if (slash == std::string_view::npos)
              break;
            c.remove_prefix(slash + 1);
            if (parts == 3)
              fail("face corner '" + std::string(t[k]) + "' has more than three indices");
          }
          const long long counts[3] = {n.positions, n.texcoords, n.normals};
          const char* names[3] = {"vertex", "texture coordinate", "normal"};
          for (int q = 0; q < parts; ++q) {
            if (part[q].empty()) {
              if (q == 0)
                fail("face corner '" + std::string(t[k]) + "' has no vertex index");
              continue;
            }
            long long i = 0;
            if (!parse_whole(part[q], i))
              fail("face corner '" + std::string(t[k]) + "': '" + std::string(part[q]) + "' is not an index");
            if (i == 0)
              fail("face corner '" + std::string(t[k]) + "' has index 0 (indices count from 1)");
            if (i < 0 && counts[q] + i < 0)
              fail("face corner '" + std::string(t[k]) + "' refers to " + names[q] + " " + std::to_string(i) +
                   ", and there are " + std::to_string(counts[q]) + " before it");
            if (i > largest[q]) {
              largest[q] = i;
              largest_line[q] = first_line;
              largest_corner[q] = std::string(t[k]);
            }
          }
        }
        ++n.faces;
      }
    }
  }
  if (in.bad())
    throw InputError(path, "", "read error");
  const long long counts[3] = {n.positions, n.texcoords, n.normals};
  const char* names[3] = {"vertex", "texture coordinate", "normal"};
  for (int q = 0; q < 3; ++q)
    if (largest[q] > counts[q])
      throw InputError(path, "line " + std::to_string(largest_line[q]),
                       "face corner '" + largest_corner[q] + "' refers to " + names[q] + " " +
                           std::to_string(largest[q]) + ", and the file has " + std::to_string(counts[q]));
  return n;
}

} // namespace curvenet::detail
