// PLY (ASCII and binary, either byte order) and OFF readers of our own.
// assimp post-processes these formats before any check: an index out of
// range or a truncated binary file crashes inside it, a header without
// `end_header` never returns, and a count of 2^31 allocates tens of GB. Here
// the header is read first, its counts are checked against the size of the
// file before anything is allocated, and every index is checked. Vertices
// keep the file's order.

#include "io/ply_off.hpp"

#include "io/file_bytes.hpp"

#include "core/numbers.hpp"
#include "curvenet/errors.hpp"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string_view>

namespace curvenet::detail {
namespace {

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f';
}

/// Whitespace-separated tokens of a text, from a position on; '#' starts a
/// comment to the end of its line (OFF).
class Tokens {
public:
  Tokens(std::string_view text, size_t at, bool comments) : text_(text), at_(at), comments_(comments) {}
  bool next(std::string_view& out) {
    for (;;) {
      while (at_ < text_.size() && is_space(text_[at_]))
        ++at_;
      if (comments_ && at_ < text_.size() && text_[at_] == '#') {
        while (at_ < text_.size() && text_[at_] != '\n')
          ++at_;
        continue;
      }
      break;
    }
    if (at_ >= text_.size())
      return false;
    const size_t start = at_;
    while (at_ < text_.size() && !is_space(text_[at_]))
      ++at_;
    out = text_.substr(start, at_ - start);
    return true;
  }
  [[nodiscard]] size_t remaining() const { return text_.size() - std::min(at_, text_.size()); }
  /// Past the end of the current line.
  void skip_line() {
    while (at_ < text_.size() && text_[at_] != '\n')
      ++at_;
  }

private:
  std::string_view text_;
  size_t at_;
  bool comments_;
};

bool parse_number(std::string_view t, double& out) {
  return parse_finite(t, out);
}
bool parse_integer(std::string_view t, long long& out) {
  return parse_whole(t, out);
}

// ---- PLY -------------------------------------------------------------------

enum class Type { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

int type_size(Type t) {
  switch (t) {
  case Type::Int8:
  case Type::UInt8:
    return 1;
  case Type::Int16:
  case Type::UInt16:
    return 2;
  case Type::Int32:
  case Type::UInt32:
  case Type::Float32:
    return 4;
  case Type::Float64:
    return 8;
  }
  return 1;
}

bool type_of(std::string_view name, Type& t) {
  static const std::pair<std::string_view, Type> names[] = {
      {"char", Type::Int8},     {"int8", Type::Int8},       {"uchar", Type::UInt8},    {"uint8", Type::UInt8},
      {"short", Type::Int16},   {"int16", Type::Int16},     {"ushort", Type::UInt16},  {"uint16", Type::UInt16},
      {"int", Type::Int32},     {"int32", Type::Int32},     {"uint", Type::UInt32},    {"uint32", Type::UInt32},
      {"float", Type::Float32}, {"float32", Type::Float32}, {"double", Type::Float64}, {"float64", Type::Float64}};
  for (const auto& [n, type] : names)
    if (n == name) {
      t = type;
      return true;
    }
  return false;
}

bool is_integral(Type t) {
  return t != Type::Float32 && t != Type::Float64;
}

struct Property {
  std::string name;
  bool list = false;
  Type count = Type::UInt8, value = Type::Float32;
};

struct Element {
  std::string name;
  long long count = 0;
  std::vector<Property> properties;
  [[nodiscard]] long long min_bytes() const { // binary: the least one record can take
    long long b = 0;
    for (const auto& p : properties)
      b += type_size(p.list ? p.count : p.value);
    return b;
  }
};

/// Reads values in one of the three encodings.
class PlyData {
public:
  enum class Format { Ascii, Little, Big };
  PlyData(const std::string& path, std::string_view text, size_t at, Format f)
      : path_(path), text_(text), at_(at), format_(f), tokens_(text, at, false) {}

  double read(Type t, const std::string& element) {
    if (format_ == Format::Ascii) {
      std::string_view tok;
      if (!tokens_.next(tok))
        throw InputError(path_, element, "the file ends before its data does");
      double v = 0;
      if (!parse_number(tok, v))
        throw InputError(path_, element, "'" + std::string(tok) + "' is not a finite number");
      if (is_integral(t) && v != std::floor(v))
        throw InputError(path_, element, "'" + std::string(tok) + "' is not an integer");
      return v;
    }
    const int n = type_size(t);
    if (at_ + n > text_.size())
      throw InputError(path_, element, "the file ends before its data does (truncated)");
    unsigned char b[8];
    std::memcpy(b, text_.data() + at_, n);
    at_ += n;
    const bool swap = (format_ == Format::Big) != (std::endian::native == std::endian::big);
    if (swap)
      std::reverse(b, b + n);
    double v = 0;
    switch (t) {
    case Type::Int8:
      v = static_cast<std::int8_t>(b[0]);
      break;
    case Type::UInt8:
      v = b[0];
      break;
    case Type::Int16: {
      std::int16_t x;
      std::memcpy(&x, b, 2);
      v = x;
      break;
    }
    case Type::UInt16: {
      std::uint16_t x;
      std::memcpy(&x, b, 2);
      v = x;
      break;
    }
    case Type::Int32: {
      std::int32_t x;
      std::memcpy(&x, b, 4);
      v = x;
      break;
    }
    case Type::UInt32: {
      std::uint32_t x;
      std::memcpy(&x, b, 4);
      v = x;
      break;
    }
    case Type::Float32: {
      float x;
      std::memcpy(&x, b, 4);
      v = x;
      break;
    }
    case Type::Float64: {
      double x;
      std::memcpy(&x, b, 8);
      v = x;
      break;
    }
    }
    if (!std::isfinite(v))
      throw InputError(path_, element, "a value is not a finite number");
    return v;
  }
  [[nodiscard]] size_t remaining() const {
    return format_ == Format::Ascii ? tokens_.remaining() : text_.size() - std::min(at_, text_.size());
  }

private:
  const std::string& path_;
  std::string_view text_;
  size_t at_;
  Format format_;
  Tokens tokens_;
};

} // namespace

RawMesh read_ply(const std::string& path) {
  const std::string file = file_bytes(path);
  const std::string_view text = file;
  // The header: lines up to `end_header`.
  std::vector<Element> elements;
  PlyData::Format format = PlyData::Format::Ascii;
  size_t at = 0;
  bool ended = false, has_format = false;
  int line_number = 0;
  while (at < text.size()) {
    const size_t end = std::min(text.find('\n', at), text.size());
    std::string_view line = text.substr(at, end - at);
    at = end + 1;
    ++line_number;
    if (!line.empty() && line.back() == '\r')
      line.remove_suffix(1);
    Tokens t(line, 0, false);
    std::string_view key;
    const std::string where = "header line " + std::to_string(line_number);
    if (line_number == 1) {
      if (line != "ply")
        throw InputError(path, where, "not a PLY file (it does not start with 'ply')");
      continue;
    }
    if (!t.next(key))
      continue;
    if (key == "end_header") {
      ended = true;
      break;
    }
    if (key == "comment" || key == "obj_info")
      continue;
    std::string_view a, b, c, d;
    if (key == "format") {
      if (!t.next(a) || !t.next(b) || b != "1.0")
        throw InputError(path, where, "expected 'format ascii|binary_little_endian|binary_big_endian 1.0'");
      if (a == "ascii")
        format = PlyData::Format::Ascii;
      else if (a == "binary_little_endian")
        format = PlyData::Format::Little;
      else if (a == "binary_big_endian")
        format = PlyData::Format::Big;
      else
        throw InputError(path, where, "unknown format '" + std::string(a) + "'");
      has_format = true;
    } else if (key == "element") {
      long long count = 0;
      if (!t.next(a) || !t.next(b) || !parse_integer(b, count) || count < 0)
        throw InputError(path, where, "expected 'element NAME COUNT' with a count of 0 or more");
      elements.push_back({std::string(a), count, {}});
    } else if (key == "property") {
      if (elements.empty())
        throw InputError(path, where, "a property before any element");
      Property p;
      if (!t.next(a))
        throw InputError(path, where, "a property without a type");
      if (a == "list") {
        p.list = true;
        if (!t.next(b) || !t.next(c) || !t.next(d) || !type_of(b, p.count) || !type_of(c, p.value) ||
            !is_integral(p.count))
          throw InputError(path, where, "expected 'property list COUNT_TYPE VALUE_TYPE NAME'");
        p.name = d;
      } else {
        if (!type_of(a, p.value) || !t.next(b))
          throw InputError(path, where, "expected 'property TYPE NAME' with a known type");
        p.name = b;
      }
      elements.back().properties.push_back(p);
    } else {
      throw InputError(path, where, "unknown header keyword '" + std::string(key) + "'");
    }
  }
  if (!ended)
    throw InputError(path, "header", "no 'end_header' line");
  if (!has_format)
    throw InputError(path, "header", "no 'format' line");

  // Counts against the file's size, before anything is allocated: a binary
  // record takes at least its scalar sizes, an ASCII one a character and a
  // separator per value.
  const size_t data_bytes = text.size() - std::min(at, text.size());
  for (const Element& e : elements) {
    const long long least =
        format == PlyData::Format::Ascii ? 2 * static_cast<long long>(e.properties.size()) : e.min_bytes();
    if (least > 0 && e.count > static_cast<long long>(data_bytes) / least)
      throw InputError(path, "element " + e.name,
                       "declares " + std::to_string(e.count) + " records, but the file's " +
                           std::to_string(data_bytes) + " bytes of data hold at most " +
                           std::to_string(static_cast<long long>(data_bytes) / least));
  }

  PlyData data(path, text, at, format);
  RawMesh raw;
  long long vertices = -1;
  std::vector<int> corners;
  for (const Element& e : elements) {
    const bool is_vertex = e.name == "vertex", is_face = e.name == "face";
    int ix = -1, iy = -1, iz = -1, ifaces = -1;
    for (size_t k = 0; k < e.properties.size(); ++k) {
      const auto& p = e.properties[k];
      if (is_vertex && !p.list && p.name == "x")
        ix = static_cast<int>(k);
      if (is_vertex && !p.list && p.name == "y")
        iy = static_cast<int>(k);
      if (is_vertex && !p.list && p.name == "z")
        iz = static_cast<int>(k);
      if (is_face && p.list && (p.name == "vertex_indices" || p.name == "vertex_index"))
        ifaces = static_cast<int>(k);
    }
    if (is_vertex && (ix < 0 || iy < 0 || iz < 0))
      throw InputError(path, "element vertex", "needs the properties x, y and z");
    if (is_face && ifaces < 0)
      throw InputError(path, "element face", "needs a list property vertex_indices");
    if (is_vertex)
      raw.positions.reserve(static_cast<size_t>(e.count));
    for (long long r = 0; r < e.count; ++r) {
      const std::string where = e.name + " " + std::to_string(r);
      Vec3 p = Vec3::Zero();
      for (size_t k = 0; k < e.properties.size(); ++k) {
        const Property& prop = e.properties[k];
        if (!prop.list) {
          const double v = data.read(prop.value, where);
          if (is_vertex && static_cast<int>(k) == ix)
            p.x() = v;
          if (is_vertex && static_cast<int>(k) == iy)
            p.y() = v;
          if (is_vertex && static_cast<int>(k) == iz)
            p.z() = v;
          continue;
        }
        const double n = data.read(prop.count, where);
        if (n < 0 || n > static_cast<double>(data.remaining()))
          throw InputError(path, where,
                           "a list of " + std::to_string(static_cast<long long>(n)) +
                               " entries does not fit in the rest of the file");
        const bool faces = is_face && static_cast<int>(k) == ifaces;
        if (faces && n < 3)
          throw InputError(path, where,
                           "a face has " + std::to_string(static_cast<long long>(n)) + " corners, needs at least 3");
        corners.clear();
        for (long long q = 0; q < static_cast<long long>(n); ++q) {
          const double v = data.read(prop.value, where);
          if (faces) {
            if (vertices < 0)
              throw InputError(path, where, "faces come before the vertices");
            if (v < 0 || v >= static_cast<double>(vertices))
              throw InputError(path, where,
                               "refers to vertex " + std::to_string(static_cast<long long>(v)) + ", and there are " +
                                   std::to_string(vertices));
            corners.push_back(static_cast<int>(v));
          }
        }
        if (faces)
          raw.add_face(corners);
      }
      if (is_vertex)
        raw.positions.push_back(p);
    }
    if (is_vertex)
      vertices = e.count;
  }
  if (vertices < 0)
    throw InputError(path, "header", "no vertex element");
  return raw;
}

// ---- OFF -------------------------------------------------------------------

RawMesh read_off(const std::string& path) {
  const std::string file = file_bytes(path);
  Tokens t(file, 0, true);
  std::string_view tok;
  if (!t.next(tok) || (tok != "OFF" && tok != "COFF" && tok != "NOFF" && tok != "CNOFF"))
    throw InputError(path, "header", "not an OFF file (it does not start with 'OFF')");
  long long counts[3] = {0, 0, 0};
  const char* names[3] = {"vertex count", "face count", "edge count"};
  for (int k = 0; k < 3; ++k)
    if (!t.next(tok) || !parse_integer(tok, counts[k]) || counts[k] < 0)
      throw InputError(path, "header", std::string("the ") + names[k] + " is missing or not a count");
  // Each vertex needs at least three numbers, each face four, each two
  // bytes at least (a digit and a separator).
  const long long room = static_cast<long long>(t.remaining());
  if (counts[0] > room / 6 || counts[1] > room / 8 || 6 * counts[0] + 8 * counts[1] > room)
    throw InputError(path, "header",
                     "declares " + std::to_string(counts[0]) + " vertices and " + std::to_string(counts[1]) +
                         " faces, more than the file's " + std::to_string(file.size()) + " bytes can hold");
  RawMesh raw;
  raw.positions.reserve(static_cast<size_t>(counts[0]));
  // One vertex a line: its position first; normals and colours (NOFF,
  // COFF) follow on the line and are skipped.
  t.skip_line();
  for (long long v = 0; v < counts[0]; ++v) {
    const std::string where = "vertex " + std::to_string(v);
    double x[3] = {0, 0, 0};
    for (double& value : x) {
      if (!t.next(tok))
        throw InputError(path, where, "the file ends before its vertices do");
      if (!parse_number(tok, value))
        throw InputError(path, where, "'" + std::string(tok) + "' is not a finite number");
    }
    t.skip_line();
    raw.positions.emplace_back(x[0], x[1], x[2]);
  }
  std::vector<int> corners;
  for (long long f = 0; f < counts[1]; ++f) {
    const std::string where = "face " + std::to_string(f);
    long long n = 0;
    if (!t.next(tok))
      throw InputError(path, where, "the file ends before its faces do");
    if (!parse_integer(tok, n) || n < 3)
      throw InputError(path, where, "'" + std::string(tok) + "' corners: a face needs at least 3");
    if (n > static_cast<long long>(t.remaining()))
      throw InputError(path, where, "a face of " + std::to_string(n) + " corners does not fit in the file");
    corners.clear();
    for (long long q = 0; q < n; ++q) {
      long long i = 0;
      if (!t.next(tok))
        throw InputError(path, where, "the file ends before its faces do");
      if (!parse_integer(tok, i))
        throw InputError(path, where, "'" + std::string(tok) + "' is not an index");
      if (i < 0 || i >= counts[0])
        throw InputError(path, where,
                         "refers to vertex " + std::to_string(i) + ", and there are " + std::to_string(counts[0]));
      corners.push_back(static_cast<int>(i));
    }
    raw.add_face(corners);
    t.skip_line(); // a face's colour may follow on its line
  }
  return raw;
}

} // namespace curvenet::detail
