#pragma once
/// \file skin.hpp
/// A mesh file's own skeleton, skin weights and animation clips, read from
/// glTF/GLB. The joints are what a rig's `skeleton` holds; the skin and the
/// clips are what the engine is measured against.

#include "curvenet/rig.hpp"

#include <array>
#include <memory>
#include <set>
#include <string>
#include <vector>

namespace curvenet {

struct SurfaceMesh; // surface_mesh.hpp

namespace detail {
struct GltfScene;
}

class SkinnedMesh {
public:
  /// Joints in an order where parents come first. `bind` is the inverse of
  /// the skin's inverse bind matrix: the joint's rest transform in the
  /// mesh's object space. A joint's parent is its nearest ancestor node that
  /// is also a joint of the skin.
  std::vector<Joint> joints;
  std::vector<Mat4> inverse_bind; ///< per joint
  /// Per vertex of the file (in read_raw_mesh's order): up to four
  /// influences as (joint index, weight), joint -1 when unused. The weights
  /// of a skinned vertex sum to 1.
  std::vector<std::array<int, 4>> vertex_joint;
  std::vector<std::array<double, 4>> vertex_weight;
  std::vector<std::string> clip_names;
  std::string source; ///< the file it was read from, for messages

  [[nodiscard]] int num_clips() const { return static_cast<int>(clip_names.size()); }
  /// A clip by name, or by index written as a number, or by the part of its
  /// name after the last '|' when one clip alone ends so ("Walk" for
  /// Blender's "Armature|Walk"). -1 when there is none.
  [[nodiscard]] int find_clip(const std::string& name_or_index) const;
  /// The time range of a clip, in seconds.
  [[nodiscard]] std::pair<double, double> clip_range(int clip) const;
  /// World transforms of the joints at time t of a clip (rest pose for clip -1),
  /// in the same space as the bind matrices.
  [[nodiscard]] std::vector<Mat4> joint_world(int clip, double t) const;
  /// Linear-blend-skinning matrices M_j = W_j(t) * inverse_bind_j.
  [[nodiscard]] std::vector<Mat4> skinning_matrices(int clip, double t) const;
  /// Where the file puts the skeleton: the rest world of the node that holds
  /// its root joints (an armature object: Blender's exports scale it by 100
  /// and turn it to Y-up), which a clip's root keys are relative to. The
  /// identity where the roots are scene roots, have parents at different
  /// places, or the file has no node hierarchy (FBX).
  [[nodiscard]] Mat4 armature() const;
  /// Where the file's rest shows each joint's bind: the rest skinning matrix
  /// of the root above it (its rest world times its inverse bind), one per
  /// joint. The identity where the file rests at its binds; the armature's
  /// scale of 100 and turn to Y up in a Blender export (times a root's own
  /// scale that its bind has and its rest lacks: the T-rex's 3). A matrix
  /// that is not a similarity (a shear, a mirror) or not finite is the
  /// identity: such a file places nothing.
  [[nodiscard]] std::vector<Mat4> rest_placing() const;
  /// The ways the file's scene may show its joints, one matrix per joint
  /// each: the armature for every joint, and rest_placing(). A way that
  /// places nothing (within a millionth of the identity, and of the
  /// skeleton's extent: a file that rests at its binds, to its floats) is
  /// left out, so a file that places nothing gives none.
  [[nodiscard]] std::vector<std::vector<Mat4>> scene_placings() const;

  std::shared_ptr<const detail::GltfScene> scene;
  std::vector<int> joint_node; ///< glTF node of each joint
};

/// The names of the skin's joints that some vertex gives a weight above zero.
std::set<std::string> weighted_joints(const SkinnedMesh& skin);

/// Reads the skin of the first skinned mesh of a glTF/GLB file (tinygltf,
/// with its clips), or the bones of an FBX file (assimp, no clips).
/// \throw InputError when the file cannot be read or has no skin.
SkinnedMesh load_skinned_mesh(const std::string& path);

/// The same through assimp, for any format it reads (used for FBX).
SkinnedMesh load_skinned_mesh_assimp(const std::string& path);

/// How a vertex blends its joints' matrices.
enum class Skinning {
  Linear,         ///< linear blend skinning: sum_j w_j M_j x
  DualQuaternion, ///< dual-quaternion skinning (Kavan et al. 2008): the joints' rigid
                  ///< motions blended as dual quaternions, after the blend of their stretches
};

/// Moves `positions` (one per file vertex) by the skin's weights.
std::vector<Eigen::Vector3d> skin_positions(const SkinnedMesh& skin, const std::vector<Eigen::Vector3d>& positions,
                                            const std::vector<Mat4>& matrices, Skinning method = Skinning::Linear);

/// The joints of a skeleton file: a skinned glTF/GLB or FBX, or a rig file
/// that has a skeleton.
/// \throw InputError when the file has none.
std::vector<Joint> load_skeleton(const std::string& path);

/// A skeleton file's joints, and, for a skinned file, the joints its skin
/// weights (the starter makes rings for those; docs/starter.md).
struct SkeletonFile {
  std::vector<Joint> joints;
  std::set<std::string> deforming; ///< empty for a rig file
  std::string note;                ///< how the joints were placed for a mesh, when they were
};
/// \throw InputError as load_skeleton() does.
SkeletonFile read_skeleton_file(const std::string& path);
/// The skeleton of `path` for `mesh`: where `path` is a skinned glTF whose
/// scene places its skeleton (Blender's exports scale it by 100 and turn it
/// to Y up), and the mesh winds round half or more of the placed joints and
/// bones' middles, and a quarter more of them than of the joints as bound,
/// the placed joints, with a note: an OBJ exported from Blender is in the
/// scene's space, not the skin's.
SkeletonFile read_skeleton_file(const std::string& path, const SurfaceMesh& mesh);
/// Whether a path names a file with skins (glTF, GLB or FBX), by its extension.
bool is_skinned_file(const std::string& path);

/// The joints of a file's skin in its mesh's space (SkinnedMesh::joints), or
/// none for a file without one: an OBJ, PLY or OFF, or a glTF, GLB or FBX
/// with no skinned mesh.
/// \throw InputError for a skin that cannot be read.
std::vector<Joint> skin_joints_if_any(const std::string& path);

/// The rig with its skeleton replaced by `joints`, which its weights name by joint name.
/// \throw InputError naming `source` and the joint when a weight names a joint the skeleton lacks.
Rig with_skeleton(Rig rig, std::vector<Joint> joints, const std::string& source);

} // namespace curvenet
