#pragma once
// glTF/GLB scenes through tinygltf: the triangle meshes of the default scene,
// the skin of the first skinned mesh, and node transforms sampled from
// animation clips. Shared by the mesh reader and the skin reader.

#include "curvenet/surface_mesh.hpp"

#include <Eigen/Core>

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace tinygltf {
class Model;
}

namespace curvenet::detail {

struct GltfScene {
  std::string path;
  std::shared_ptr<const tinygltf::Model> model;
  RawMesh mesh;                        ///< every triangle primitive, in traversal order
  std::vector<Eigen::Vector2d> uv;     ///< per mesh vertex (TEXCOORD_0), empty when no primitive has one
  std::vector<Eigen::Vector3d> normal; ///< per mesh vertex (NORMAL), empty when no primitive has one
  std::vector<int> face_material;      ///< per triangle, its primitive's material (-1 for none)
  std::vector<int> node_parent;        ///< per node, -1 for roots
  int skin = -1;                       ///< the skin of the first skinned mesh node, or -1
  /// Per mesh vertex: up to 4 (skin joint slot, weight); slot -1 when unused.
  std::vector<std::array<int, 4>> vertex_joint;
  std::vector<std::array<double, 4>> vertex_weight;
  /// Vertices read so far, by the accessors and placement they came from:
  /// primitives that share their vertex accessors (materials over one vertex
  /// buffer, as `curvenet bake` writes them) share the vertices.
  struct VertexSource {
    std::array<int, 5> accessors; ///< POSITION, NORMAL, TEXCOORD_0, JOINTS_0, WEIGHTS_0 (-1: none)
    Eigen::Matrix4d world;
    bool skinned;
    int base; ///< the first of its vertices in `mesh`
  };
  std::vector<VertexSource> vertex_sources;
};

/// Reads a .gltf or .glb file. The last two files parsed are kept with a
/// hash of their bytes, so a command that takes a file's surface, topology
/// and skin parses it once; changed bytes are parsed again.
/// \throw InputError for an unreadable file or a malformed accessor.
GltfScene read_gltf_scene(const std::string& path);

/// How many glTF files this process has parsed (for tests of the above).
long gltf_parses();
/// Forgets the parses kept (for benchmarks that time a parse).
void forget_gltf_parses();

/// World matrices of every node, at time `t` (seconds) of animation `clip`,
/// or at rest when clip < 0. Channels interpolate as their samplers say
/// (LINEAR, STEP, CUBICSPLINE); times outside a channel hold its end value.
std::vector<Eigen::Matrix4d> node_world_matrices(const GltfScene& scene, int clip, double t);

/// The inverse bind matrices of the scene's skin, one per skin joint slot.
std::vector<Eigen::Matrix4d> inverse_bind_matrices(const GltfScene& scene);

} // namespace curvenet::detail
