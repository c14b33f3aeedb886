#pragma once
// Reading JSON text for the rig and pose files: every fault of the text
// itself is refused with the file, the line and the column, and keys are
// unique in every object (nlohmann keeps the last of two silently).

#include <nlohmann/json.hpp>

#include <string>

namespace curvenet::detail {

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
