#pragma once
// OBJ, read strictly in one pass over the file's bytes. Every number must be
// a whole, finite number, every index must refer to an element that exists,
// and every face must have three corners (tinyobjloader, which this reader
// replaced, reads `nan`, `abc`, `1,5` or a missing coordinate as 0 or as a
// prefix, and drops faces it cannot use, so it needed a checking pass of its
// own first: two parses of every file). The file's vertex order is kept.

#include "curvenet/surface_mesh.hpp"

#include <Eigen/Core>

#include <memory>
#include <string>
#include <vector>

namespace curvenet::detail {

/// An OBJ file's geometry: positions, texture coordinates, normals, and its
/// faces in file order with each corner's indices (from 0; -1 where the
/// corner has none). Lines other than v, vt, vn and f are ignored.
struct ObjData {
  std::vector<Vec3> positions;
  std::vector<Eigen::Vector2d> texcoords; ///< u, v (v is 0 where the file gives u alone)
  std::vector<Vec3> normals;
  std::vector<int> face_offsets{0}; ///< #faces + 1 offsets into the corner arrays
  std::vector<int> corner_vertex, corner_texcoord, corner_normal;
};

/// \throw InputError naming the file and the line (`line 12`) of the first
/// fault: a coordinate that is not a finite number, too few coordinates, an
/// index of 0 or out of range (negative indices count back from the element
/// before the face, as the format says), or a face with fewer than three
/// corners. `bytes` are the file's (`path` names it in messages).
ObjData read_obj_bytes(const std::string& path, const std::string& bytes);

/// An OBJ file read (read_obj_bytes) once: the last file read is kept with
/// a hash of its bytes, so that a command reading a file's surface and its
/// topology parses it once, and a file whose bytes changed is parsed again.
/// \throw InputError as read_obj_bytes does, or for a file it cannot read.
std::shared_ptr<const ObjData> parse_obj(const std::string& path);

/// How many OBJ files this process has parsed (for tests of the above).
long obj_parses();
/// Forgets the parse kept (for benchmarks that time a parse).
void forget_obj_parse();

} // namespace curvenet::detail
