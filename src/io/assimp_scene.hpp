#pragma once
// PLY, OFF and FBX (and anything else assimp reads) through assimp: the
// polygons of every mesh node, in world space, and the bones that skin them.
// Shared by the mesh reader and the skin reader, so both see the vertices in
// the same order.

#include "curvenet/rig.hpp"
#include "curvenet/surface_mesh.hpp"

#include <array>
#include <string>
#include <vector>

namespace curvenet::detail {

struct AssimpScene {
  RawMesh mesh;
  std::vector<Joint> joints;                        ///< bones, parents first, bind in the mesh's (world) space
  std::vector<std::array<int, 4>> vertex_joint;     ///< per vertex, -1 when unused
  std::vector<std::array<double, 4>> vertex_weight; ///< normalised
};

/// \throw InputError for an unreadable file.
AssimpScene read_assimp_scene(const std::string& path);

} // namespace curvenet::detail
