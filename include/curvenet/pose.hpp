#pragma once
/// \file pose.hpp
/// Poses: per-joint local transforms relative to the rest pose (pose files,
/// or sampled from glTF clips), and the skinning matrices they give.

#include "curvenet/rig.hpp"
#include "curvenet/skin.hpp"

#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace curvenet {

/// A joint's pose entry L = T R S, in the joint's own rest frame.
struct JointPose {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
  [[nodiscard]] Mat4 matrix() const;
};

/// Joint name -> pose entry. Joints that are not listed stay at rest.
using Pose = std::map<std::string, JointPose>;

/// Per node id: an offset in rest space that turns with the node's joints
/// (layer.hpp: the curves through the node, and the mesh inside the regions
/// they bound, follow it).
using NodeOffsets = std::map<std::string, Eigen::Vector3d>;

/// A pose file: its joints' entries, and (version 2) its nodes' offsets.
struct PoseFile {
  Pose joints;
  NodeOffsets nodes;
};

/// Reads a pose file (`"format": "curvenet-pose"`, version 1 or 2; only
/// version 2 may have `nodes`).
/// \throw InputError with the JSON path of the fault: unknown keys, a
///   rotation whose norm is not within 1e-6 of 1, malformed JSON.
PoseFile read_pose_file(const std::string& path);
PoseFile parse_pose_file(const std::string& text, const std::string& source);
/// The joints' entries of a pose file (read_pose_file().joints).
Pose read_pose(const std::string& path);
Pose parse_pose(const std::string& text, const std::string& source);

/// Skinning matrices M_j = G_j B_j^-1 with G_j = G_p (B_p^-1 B_j) L_j (for a
/// root, G_j = B_j L_j), one per joint.
/// \throw InputError when the pose names a joint the skeleton lacks.
std::vector<Mat4> skinning_matrices(const std::vector<Joint>& joints, const Pose& pose,
                                    const std::string& source = "pose");

/// The pose of a glTF clip at time t, as entries against the rest pose that
/// the file's own inverse bind matrices define, for the file's joints (by
/// name). Applied to a rig's own bind matrices, it drives that rig the same
/// way, even on another mesh.
Pose pose_from_clip(const SkinnedMesh& file, int clip, double t);

/// Whether `rig`'s skeleton is the file's as its armature places it (within
/// a hundredth of the skeleton's size), and not the file's binds: a mesh
/// exported with the armature applied (as Blender re-exports a glTF whose
/// armature scales it), or a rig transferred to one. The clips' root keys
/// carry the armature; such a rig takes them against the placed rest.
bool placed_by_armature(const std::vector<Joint>& rig, const SkinnedMesh& clips);

/// pose_from_clip's entries for the joints `rig` shares with the file, by
/// name; where placed_by_armature, the roots' entries are taken against
/// the armature's rest, so that the armature moves the rig once, not twice.
Pose clip_pose_for(const std::vector<Joint>& rig, const SkinnedMesh& clips, int clip, double t);

/// Skinning matrices for `joints` at time t of a clip, matched to the clip's
/// joints by name (clip_pose_for); joints the clip lacks stay at rest.
/// \throw InputError when no joint of the clip matches one of `joints`.
std::vector<Mat4> clip_skinning_matrices(const std::vector<Joint>& joints, const SkinnedMesh& clips, int clip,
                                         double t);

/// clip_skinning_matrices() frame after frame: how the file places the
/// rig (placed_by_armature) is worked out once, not at every frame. Holds
/// references to `joints` and `clips`, which must outlive it.
class ClipPoser {
public:
  ClipPoser(const std::vector<Joint>& joints, const SkinnedMesh& clips);
  ClipPoser(std::vector<Joint>&&, const SkinnedMesh&) = delete; // it would hold a temporary
  ClipPoser(const std::vector<Joint>&, SkinnedMesh&&) = delete;
  /// \throw InputError as clip_skinning_matrices() does.
  [[nodiscard]] std::vector<Mat4> operator()(int clip, double t) const;

private:
  const std::vector<Joint>& joints_;
  const SkinnedMesh& clips_;
  std::optional<std::vector<Mat4>> placing_;
};

/// The whole frames a clip spans at `fps`, first and last: its start
/// rounded down and its end rounded up.
std::pair<int, int> clip_frames(const SkinnedMesh& clips, int clip, double fps);

} // namespace curvenet
