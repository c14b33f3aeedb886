#include "io/json_text.hpp"

#include "curvenet/errors.hpp"

#include <optional>
#include <set>
#include <vector>

namespace curvenet::detail {

std::string line_column(const std::string& text, size_t byte) {
  size_t line = 1, col = 1;
  for (size_t i = 0; i < byte && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      col = 1;
    } else {
      ++col;
    }
  }
  return "line " + std::to_string(line) + ", column " + std::to_string(col);
}

namespace {

struct Duplicate {
  size_t byte = 0;
  std::string key, path;
};

/// Walks a text that parsed as JSON, calling `visit(path, byte)` at the
/// start of every value (and at every key, with the member's path), and
/// reporting the first key that appears twice in one object.
template <class Visit> std::optional<Duplicate> walk_json(const std::string& t, Visit&& visit) {
  struct Frame {
    bool object = false;
    std::set<std::string> keys;
    std::string path;     // of this container
    std::string key;      // the current member's key (objects)
    long long index = -1; // the current element (arrays)
    bool expect_key = true;
  };
  std::vector<Frame> stack;
  auto child_path = [&]() {
    if (stack.empty())
      return std::string();
    const Frame& f = stack.back();
    return f.path + "/" + (f.object ? f.key : std::to_string(f.index));
  };
  auto element_starts = [&](size_t at) { // a value begins in the current container
    if (!stack.empty() && !stack.back().object)
      ++stack.back().index;
    visit(child_path(), at);
  };
  for (size_t i = 0; i < t.size(); ++i) {
    const char c = t[i];
    if (c == '"') {
      const size_t start = i;
      std::string s;
      for (++i; i < t.size() && t[i] != '"'; ++i) {
        if (t[i] != '\\' || i + 1 >= t.size()) {
          s += t[i];
          continue;
        }
        // An escape, decoded as nlohmann decodes it (so paths match).
        const char e = t[++i];
        if (e == 'n')
          s += '\n';
        else if (e == 't')
          s += '\t';
        else if (e == 'r')
          s += '\r';
        else if (e == 'b')
          s += '\b';
        else if (e == 'f')
          s += '\f';
        else if (e == 'u' && i + 4 < t.size()) {
          const unsigned cp = static_cast<unsigned>(std::stoul(t.substr(i + 1, 4), nullptr, 16));
          i += 4;
          if (cp < 0x80) {
            s += static_cast<char>(cp);
          } else if (cp < 0x800) {
            s += static_cast<char>(0xC0 | (cp >> 6));
            s += static_cast<char>(0x80 | (cp & 0x3F));
          } else {
            s += static_cast<char>(0xE0 | (cp >> 12));
            s += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
            s += static_cast<char>(0x80 | (cp & 0x3F));
          }
        } else
          s += e; // \" \\ \/
      }
      if (!stack.empty() && stack.back().object && stack.back().expect_key) {
        Frame& f = stack.back();
        if (!f.keys.insert(s).second)
          return Duplicate{start, s, f.path + "/" + s};
        f.key = s;
        f.expect_key = false;
        visit(f.path + "/" + s, start);
      } else {
        element_starts(start);
      }
    } else if (c == '{' || c == '[') {
      element_starts(i);
      Frame f;
      f.object = c == '{';
      f.path = child_path();
      stack.push_back(std::move(f));
    } else if (c == '}' || c == ']') {
      if (!stack.empty())
        stack.pop_back();
    } else if (c == ',') {
      if (!stack.empty() && stack.back().object)
        stack.back().expect_key = true;
    } else if (c != ':' && c != ' ' && c != '\n' && c != '\r' && c != '\t') {
      // A number, true, false or null: one element.
      element_starts(i);
      while (i + 1 < t.size() && t[i + 1] != ',' && t[i + 1] != '}' && t[i + 1] != ']' && t[i + 1] != ' ' &&
             t[i + 1] != '\n' && t[i + 1] != '\r' && t[i + 1] != '\t')
        ++i;
    }
  }
  return std::nullopt;
}

} // namespace

std::optional<size_t> too_deep(std::string_view text, int limit) {
  int depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\')
        ++i;
      else if (c == '"')
        in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > limit)
        return i;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return std::nullopt;
}

nlohmann::ordered_json parse_json(const std::string& text, const std::string& source) {
  // Nesting is bounded before parsing: a parser recurses (or allocates) per level.
  if (const auto at = too_deep(text, kMaxJsonDepth))
    throw InputError(source, line_column(text, *at),
                     "JSON nested more than " + std::to_string(kMaxJsonDepth) + " levels deep");
  nlohmann::ordered_json root;
  try {
    root = nlohmann::ordered_json::parse(text);
  } catch (const nlohmann::ordered_json::parse_error& e) {
    std::string what = e.what();
    const auto pos = what.find("syntax error");
    throw InputError(source, line_column(text, e.byte > 0 ? e.byte - 1 : 0),
                     "malformed JSON: " + (pos == std::string::npos ? what : what.substr(pos)));
  } catch (const nlohmann::ordered_json::out_of_range& e) {
    // A number too large for a double: find the token for its place.
    const std::string what = e.what();
    const auto q = what.find('\'');
    const std::string token = q == std::string::npos ? "" : what.substr(q + 1, what.rfind('\'') - q - 1);
    const size_t at = token.empty() ? std::string::npos : text.find(token);
    throw InputError(source, at == std::string::npos ? std::string("") : line_column(text, at),
                     "the number " + (token.empty() ? std::string("") : "'" + token + "' ") +
                         "is out of range (not a finite number)");
  }
  if (const auto d = walk_json(text, [](const std::string&, size_t) {}))
    throw InputError(source, d->path + " (" + line_column(text, d->byte) + ")",
                     "the key '" + d->key + "' appears twice in one object");
  return root;
}

std::string json_place(const std::string& text, const std::string& path) {
  size_t found = std::string::npos;
  walk_json(text, [&](const std::string& p, size_t at) {
    if (found == std::string::npos && p == path)
      found = at;
  });
  return found == std::string::npos ? std::string() : line_column(text, found);
}

long long json_integer(const nlohmann::ordered_json& j, const std::string& source, const std::string& path,
                       long long lo, long long hi) {
  auto fail = [&]() -> long long {
    throw InputError(source, path,
                     "expected an integer from " + std::to_string(lo) + " to " + std::to_string(hi) + ", not " +
                         j.dump());
  };
  if (j.is_number_unsigned()) {
    const auto v = j.get<unsigned long long>();
    if (v > static_cast<unsigned long long>(hi) || static_cast<long long>(v) < lo)
      return fail();
    return static_cast<long long>(v);
  }
  if (!j.is_number_integer())
    return fail();
  const auto v = j.get<long long>();
  if (v < lo || v > hi)
    return fail();
  return v;
}

} // namespace curvenet::detail
