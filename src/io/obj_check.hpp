#pragma once
// A strict reading of an OBJ file's geometry lines before tinyobjloader
// parses it: tinyobjloader reads `nan`, `abc`, `1,5` or a missing
// coordinate as 0 or as a prefix, and drops faces it cannot use. Here every
// number must be a whole, finite number, every index must refer to an
// element that exists, and every face must have three corners.

#include <memory>
#include <string>

namespace tinyobj {
class ObjReader;
}

namespace curvenet::detail {

/// Counts of an OBJ file's elements, once it has passed the check.
struct ObjCounts {
  long long positions = 0, texcoords = 0, normals = 0, faces = 0;
};

/// \throw InputError naming the file and the line (`line 12`) of the first
/// fault: a coordinate that is not a finite number, too few coordinates, an
/// index of 0 or out of range (negative indices count back from the element
/// before the face, as the format says), or a face with fewer than three
/// corners. `bytes` are the file's (`path` names it in messages).
ObjCounts check_obj(const std::string& path, const std::string& bytes);

/// An OBJ file checked (check_obj) and parsed by tinyobjloader, once: the
/// last file parsed is kept with a hash of its bytes, so that a command
/// reading a file's surface and its topology parses it once, and a file
/// whose bytes changed is parsed again.
/// \throw InputError for a fault check_obj finds or tinyobjloader reports.
std::shared_ptr<const tinyobj::ObjReader> parse_obj(const std::string& path);

/// How many OBJ files this process has parsed (for tests of the above).
long obj_parses();
/// Forgets the parse kept (for benchmarks that time a parse).
void forget_obj_parse();

} // namespace curvenet::detail
