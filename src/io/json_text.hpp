#pragma once
// Reading JSON text for the rig and pose files: every fault of the text
// itself is refused with the file, the line and the column, and keys are
// unique in every object (nlohmann keeps the last of two silently).

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <string_view>

namespace curvenet::detail {

/// The deepest nesting of arrays and objects a JSON input may have (a rig
/// needs 5 levels, a glTF file fewer than 10).
constexpr int kMaxJsonDepth = 64;

/// The byte at which `text` first nests arrays and objects deeper than
/// `limit` (strings skipped), if it does.
std::optional<size_t> too_deep(std::string_view text, int limit);

/// \throw InputError naming `source` and the line and column: malformed
///   JSON, a number out of range (1e999), or a key that appears twice in one
///   object (then also the key's JSON path).
nlohmann::ordered_json parse_json(const std::string& text, const std::string& source);

/// The 1-based line and column of a byte offset in a text.
std::string line_column(const std::string& text, size_t byte);

/// "line L, column C" of the value at a JSON path ("/nodes/1/id") in a text
/// that parses, or "" when there is none.
std::string json_place(const std::string& text, const std::string& path);

/// A JSON integer in [lo, hi], exactly (4294967297 is not 1).
/// \throw InputError naming `source` and `path` otherwise.
long long json_integer(const nlohmann::ordered_json& j, const std::string& source, const std::string& path,
                       long long lo, long long hi);

} // namespace curvenet::detail
