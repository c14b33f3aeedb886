#include "io/obj_read.hpp"

#include "core/numbers.hpp"
#include "curvenet/errors.hpp"
#include "io/file_bytes.hpp"

#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>
#include <optional>
#include <string_view>
#include <utility>

namespace curvenet::detail {
namespace {

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

/// The tokens of one line, read one at a time (no line is copied).
struct Tokens {
  const char* p;
  const char* end;
  std::string_view next() {
    while (p < end && is_space(*p))
      ++p;
    const char* b = p;
    while (p < end && !is_space(*p))
      ++p;
    return {b, static_cast<size_t>(p - b)};
  }
};

enum Kind { kVertex = 0, kTexcoord = 1, kNormal = 2 };
const char* const kNames[3] = {"vertex", "texture coordinate", "normal"};

} // namespace

ObjData read_obj_bytes(const std::string& path, const std::string& bytes) {
  ObjData out;
  // A positive index may refer to an element further down the file; it is
  // checked at the end, against the line of the largest one.
  long long largest[3] = {0, 0, 0}, largest_line[3] = {0, 0, 0};
  std::string largest_corner[3];
  long long line_no = 0;
  auto fail = [&](const std::string& what) { throw InputError(path, "line " + std::to_string(line_no), what); };
  auto count = [&](int q) {
    return static_cast<long long>(q == kVertex     ? out.positions.size()
                                  : q == kTexcoord ? out.texcoords.size()
                                                   : out.normals.size());
  };
  // Reads `least` to `most` coordinates into xyz (the rest of the line, up
  // to `most`, must be numbers too; tokens past `most` are not read).
  auto coordinates = [&](Tokens& t, int least, int most, const char* what, double* xyz) {
    int k = 0;
    for (std::string_view tok = t.next(); !tok.empty() && k < most; tok = t.next(), ++k) {
      double x = 0;
      if (!parse_finite(tok, x))
        fail(std::string(what) + (std::string(what).ends_with("coordinate") ? " '" : " coordinate '") + std::string(tok) +
             "' is not a finite number");
      if (k < 3)
        xyz[k] = x;
    }
    if (k < least)
      fail(std::string(what) + " has " + std::to_string(k) + " coordinates, needs " + std::to_string(least));
  };
  const char* p = bytes.data();
  const char* const end = p + bytes.size();
  if (bytes.rfind("\xEF\xBB\xBF", 0) == 0)
    p += 3; // a UTF-8 byte order mark, which some Windows tools write first
  // A line that ends in a backslash goes on on the next (the OBJ format's
  // line continuation): such lines, rare, are joined in a buffer; every
  // other line is read where it lies. An error names the first line.
  std::string joined;
  auto next_eol = [&](const char* from) {
    const char* e = static_cast<const char*>(std::memchr(from, '\n', static_cast<size_t>(end - from)));
    return e ? e : end;
  };
  auto continues = [](const char* b, const char* e) { // the line [b, e) ends in a backslash, not in a comment
    if (e > b && e[-1] == '\r')
      --e;
    return e > b && e[-1] == '\\' && !std::memchr(b, '#', static_cast<size_t>(e - b));
  };
  long long continued_lines = 0; // of the line before, read with it
  while (p < end) {
    line_no += 1 + std::exchange(continued_lines, 0);
    const char* eol = next_eol(p);
    const char* b = p;
    long long more_lines = 0;
    if (continues(p, eol)) {
      joined.clear();
      const char* from = p;
      const char* to = eol;
      for (;;) {
        const bool cont = continues(from, to), on = cont && to < end;
        const char* stop = to;
        if (cont) { // the backslash goes, at the end of the file too
          if (stop > from && stop[-1] == '\r')
            --stop;
          --stop; // the backslash
        }
        joined.append(from, stop);
        if (!on)
          break;
        joined += ' ';
        from = to + 1;
        to = next_eol(from);
        ++more_lines;
      }
      eol = to;
      b = joined.data();
    }
    continued_lines = more_lines;
    const bool in_joined = b != p; // (a last line ending in a backslash is joined with nothing)
    const char* line_end = in_joined ? joined.data() + joined.size() : eol;
    const char* hash = static_cast<const char*>(std::memchr(b, '#', static_cast<size_t>(line_end - b)));
    Tokens t{b, hash ? hash : line_end};
    p = eol + (eol < end ? 1 : 0);
    const std::string_view key = t.next();
    if (key == "v") {
      double xyz[3] = {0, 0, 0};
      coordinates(t, 3, 7, "vertex", xyz);
      out.positions.emplace_back(xyz[0], xyz[1], xyz[2]);
    } else if (key == "vt") {
      double uvw[3] = {0, 0, 0};
      coordinates(t, 1, 3, "texture coordinate", uvw);
      out.texcoords.emplace_back(uvw[0], uvw[1]);
    } else if (key == "vn") {
      double xyz[3] = {0, 0, 0};
      coordinates(t, 3, 3, "normal", xyz);
      out.normals.emplace_back(xyz[0], xyz[1], xyz[2]);
    } else if (key == "f") {
      int corners = 0;
      for (std::string_view tok = t.next(); !tok.empty(); tok = t.next(), ++corners) {
        // v, v/vt, v//vn or v/vt/vn
        std::string_view c = tok, part[3];
        int parts = 0;
        while (parts < 3) {
          const size_t slash = c.find('/');
          part[parts++] = c.substr(0, slash);
          if (slash == std::string_view::npos)
            break;
          c.remove_prefix(slash + 1);
          if (parts == 3)
            fail("face corner '" + std::string(tok) + "' has more than three indices");
        }
        int index[3] = {-1, -1, -1};
        for (int q = 0; q < parts; ++q) {
          if (part[q].empty()) {
            if (q == 0)
              fail("face corner '" + std::string(tok) + "' has no vertex index");
            continue;
          }
          long long i = 0;
          if (!parse_whole(part[q], i))
            fail("face corner '" + std::string(tok) + "': '" + std::string(part[q]) + "' is not an index");
          if (i == 0)
            fail("face corner '" + std::string(tok) + "' has index 0 (indices count from 1)");
          const long long n = count(q);
          if (i < 0 && n + i < 0)
            fail("face corner '" + std::string(tok) + "' refers to " + kNames[q] + " " + std::to_string(i) +
                 ", and there are " + std::to_string(n) + " before it");
          if (i > largest[q]) {
            if (i > std::numeric_limits<int>::max())
              fail("face corner '" + std::string(tok) + "' refers to " + kNames[q] + " " + std::to_string(i) +
                   ", past what a mesh can hold");
            largest[q] = i;
            largest_line[q] = line_no;
            largest_corner[q] = std::string(tok);
          }
          index[q] = static_cast<int>(i < 0 ? n + i : i - 1);
        }
        out.corner_vertex.push_back(index[kVertex]);
        out.corner_texcoord.push_back(index[kTexcoord]);
        out.corner_normal.push_back(index[kNormal]);
      }
      if (corners < 3)
        fail("face has " + std::to_string(corners) + " corners, needs at least 3");
      if (out.corner_vertex.size() > static_cast<size_t>(std::numeric_limits<int>::max()))
        fail("the file has more face corners than a mesh can hold");
      out.face_offsets.push_back(static_cast<int>(out.corner_vertex.size()));
    }
  }
  for (int q = 0; q < 3; ++q)
    if (largest[q] > count(q))
      throw InputError(path, "line " + std::to_string(largest_line[q]),
                       "face corner '" + largest_corner[q] + "' refers to " + kNames[q] + " " +
                           std::to_string(largest[q]) + ", and the file has " + std::to_string(count(q)));
  return out;
}

namespace {
struct ObjCache {
  std::mutex mutex;
  std::string path;
  size_t size = 0, hash = 0;      ///< of the bytes: a file rewritten within the clock's tick keeps its mtime
  std::optional<FileStamp> stamp; ///< settled when read: then an unchanged stamp needs no second read
  std::shared_ptr<const ObjData> data;
  long parses = 0;
};
ObjCache& obj_cache() {
  static ObjCache cache;
  return cache;
}
} // namespace

void forget_obj_parse() {
  ObjCache& c = obj_cache();
  std::lock_guard lock(c.mutex);
  c.data.reset();
  c.stamp.reset();
}

long obj_parses() {
  ObjCache& c = obj_cache();
  std::lock_guard lock(c.mutex);
  return c.parses;
}

std::shared_ptr<const ObjData> parse_obj(const std::string& path) {
  std::error_code ec;
  const std::string key = std::filesystem::absolute(path, ec).lexically_normal().string();
  const std::optional<FileStamp> stamp = settled_stamp(path);
  ObjCache& c = obj_cache();
  {
    std::lock_guard lock(c.mutex);
    if (c.data && c.path == key && stamp && c.stamp == stamp)
      return c.data; // a settled file, unchanged: not read again
  }
  const std::string bytes = file_bytes(path);
  const size_t hash = std::hash<std::string_view>{}(bytes);
  {
    std::lock_guard lock(c.mutex);
    if (c.data && c.path == key && c.size == bytes.size() && c.hash == hash) {
      c.stamp = stamp;
      return c.data;
    }
  }
  auto data = std::make_shared<const ObjData>(read_obj_bytes(path, bytes));
  std::lock_guard lock(c.mutex);
  ++c.parses;
  c.path = key;
  c.size = bytes.size();
  c.hash = hash;
  c.stamp = stamp;
  c.data = data;
  return data;
}

} // namespace curvenet::detail
