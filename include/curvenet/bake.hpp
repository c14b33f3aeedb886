#pragma once
/// \file bake.hpp
/// Baking a binding to an ordinary linear-blend skin, for engines and tools
/// that read skins and not Curvenets: per input vertex, the k largest
/// harmonic joint weights s_j = H(w_j), renormalised (or weights fitted to the
/// full deformation over sample poses), and a skinned glTF 2.0 binary.
/// The weights come from the net, not from the mesh's vertices, so every
/// tessellation the rig is transferred to gets a skin that agrees (docs/bake.md).

#include "curvenet/deform.hpp"
#include "curvenet/rig.hpp"
#include "curvenet/skin.hpp"

#include <array>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace curvenet {

/// A linear-blend skin: `influences` slots per input vertex.
struct SkinWeights {
  int influences = 4;
  std::vector<std::string> joints; ///< joint names; `joint` indexes them
  std::vector<int> joint;          ///< vertices x influences, -1 for an unused slot
  std::vector<double> weight;      ///< vertices x influences, largest first; each vertex's sum is 1
  /// Helper joints, listed after the rig's in `joints`: helper i (joint
  /// `rig_joints() + i`) is half way between rig joints helpers[i][0] and
  /// helpers[i][1], its skinning matrix the dual-quaternion mean of theirs
  /// (helper_matrix). Empty for a skin of the rig's joints alone.
  std::vector<std::array<int, 2>> helpers;
  [[nodiscard]] int num_vertices() const { return influences > 0 ? static_cast<int>(joint.size()) / influences : 0; }
  [[nodiscard]] int rig_joints() const { return static_cast<int>(joints.size() - helpers.size()); }
};

/// A helper joint's skinning matrix: the dual-quaternion mean of two
/// joints' skinning matrices (their rotations and translations blended half
/// and half as unit dual quaternions, the short way round), scaled by the
/// mean of their volume scales (the cube roots of their determinants). A
/// similarity, so that a glTF node carries it exactly in any pose (a
/// non-uniform stretch would need a shear no node's TRS has); rigid when
/// both are; the identity when both are.
Mat4 helper_matrix(const Mat4& a, const Mat4& b);

/// `skinning` (one matrix per rig joint of the weights) followed by each
/// helper's matrix: one matrix per joint of the weights.
/// \throw Error when `skinning` has not one matrix per rig joint.
std::vector<Mat4> with_helpers(const SkinWeights& weights, std::span<const Mat4> skinning);

/// The largest `max_influences` harmonic weights s_j of each input vertex,
/// renormalised to sum to 1 (the binding's own joint order).
/// \throw InputError when max_influences is not between 1 and 8.
SkinWeights bake_weights(const Binding& binding, int max_influences = 4);

/// Weights that bring linear blend skinning closest to the binding's own
/// deformation over `poses` (skinning matrices per pose): per vertex, least
/// squares over the poses, non-negative and summing to 1, on at most
/// `max_influences` of the joints that bound the vertex's region, pulled
/// gently towards the harmonic weights where the poses leave them free.
///
/// With `helpers` > 0 the fit may also use up to that many helper joints
/// (SkinWeights::helpers), each half way between two joints that bound a
/// vertex together: every such pair is first offered to every vertex it
/// could serve, each pair is ranked by the most any vertex owes it (that
/// vertex's weight on the pair times how much closer, in root mean square
/// over the poses, it comes with the pairs than without), and the fit is
/// redone with the best `helpers` pairs (a chosen pair that ends with no
/// weight on any vertex is dropped). A linear skin follows a dual-quaternion blend only to first
/// order in the joints' turn; a helper keyed half way round a bend carries
/// the arc a bent knee or ankle needs (docs/bake.md).
/// \throw InputError when max_influences is not between 1 and 8, helpers is
///   negative, or a pose has the wrong number of matrices.
SkinWeights fit_weights(const Binding& binding, const std::vector<std::vector<Mat4>>& poses, int max_influences = 4,
                        int helpers = 0);

/// The same fit to another deformation of the binding's vertices (a layer
/// over the skin, layer.hpp): `deform_frames` as Binding::deform_frames,
/// and `candidates(v, influences)` given each vertex's harmonic influences
/// to change into the joints to fit over, with the weights the pull goes
/// towards.
SkinWeights fit_weights(const Binding& binding, const std::vector<std::vector<Mat4>>& poses, int max_influences,
                        const std::function<void(std::span<const Mat4>, std::span<Vec3>)>& deform_frames,
                        const std::function<void(int, std::vector<std::pair<int, double>>&)>& candidates,
                        int helpers = 0);

/// How training_poses() moves the skeleton. The angles are moderate on
/// purpose: a linear skin can follow the rig's first-order response to each
/// joint, but not a dual-quaternion blend at 90 degrees, and fitting there
/// bends the weights towards a compromise that a clip's moderate poses pay
/// for (docs/bake.md measures both).
struct TrainingPoses {
  std::vector<double> bends{10, 20}; ///< degrees, each joint alone, both ways about both axes across its bone
  double twist = 10;                 ///< degrees, each joint alone about its bone, both ways
  int random_poses = 48;             ///< poses that move every joint at once
  double random_bend = 15, random_twist = 10; ///< their largest angles, degrees
  unsigned seed = 1;
};

/// Poses from the skeleton alone, for a fit without the user's clips: skinning
/// matrices (one per joint, the order of `joints`, mesh space) of each joint
/// bent and twisted on its own, then of random poses of every joint at once.
/// A joint's bone runs to the mean of its children (a leaf continues its
/// parent's). \throw InputError for a non-finite bind matrix, a non-finite
/// angle or a negative count.
std::vector<std::vector<Mat4>> training_poses(const std::vector<Joint>& joints, const TrainingPoses& options = {});

/// Skinning with these weights: `rest` (one position per input vertex) moved
/// by `skinning` (one matrix per joint of the weights, or per rig joint,
/// the helpers' then following by with_helpers), linearly or by dual
/// quaternions.
std::vector<Vec3> skin_positions(const SkinWeights& weights, std::span<const Vec3> rest, std::span<const Mat4> skinning,
                                 Skinning method = Skinning::Linear);

/// The weights as CSV: a header, then one row per input vertex
/// (`vertex,joint_0,weight_0,...`), joints by name, empty where unused.
std::string weights_csv(const SkinWeights& weights);

struct GltfBakeOptions {
  /// The source's up axis. glTF is Y-up; a Z-up source (Blender, 3ds Max)
  /// is turned by -90 degrees about X (x, y, z) -> (x, z, -y), its skeleton
  /// and clips with it. Units are kept (glTF reads them as metres).
  enum class Up { Y, Z } up = Up::Y;
  /// Clips are sampled at this rate (one key per frame, LINEAR).
  double fps = 24;
  /// Clip names to include from the clip file; empty for all of them.
  std::vector<std::string> clips;
};

/// A skinned glTF 2.0 binary (GLB) of the mesh file `mesh_path`: its faces
/// on its own vertex order (vertices whose corners carry different UVs or
/// normals are split, the extra copies after the file's own vertices), its
/// UVs and normals where it has them, and, for a glTF source, its materials
/// and images; `joints` (mesh space, parents first) as a node hierarchy with
/// inverseBindMatrices; JOINTS_0/WEIGHTS_0 (and _1 past four influences);
/// and, when `clips` is given, its animations retargeted to the joints by name.
/// A helper joint of the weights is a node under the deeper of its two
/// joints, at that joint's rest frame, keyed in every clip so that its
/// skinning matrix is helper_matrix of theirs; where a clip scales or
/// flattens that joint so that no local TRS under it can carry the helper,
/// it is a root node instead, at a rigid frame (that joint's rest position
/// and turn, and its volume scale). Its `extras` name the two
/// (`{"curvenet_helper": ["a", "b"]}`) for an engine that plays clips of
/// its own and must drive it.
/// \throw InputError when the weights do not fit the mesh or the joints, or a
///   clip named in the options is not in the clip file.
std::string skinned_glb(const std::string& mesh_path, const std::vector<Joint>& joints, const SkinWeights& weights,
                        const SkinnedMesh* clips = nullptr, const GltfBakeOptions& options = {});

} // namespace curvenet
