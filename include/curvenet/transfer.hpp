#pragma once
/// \file transfer.hpp
/// Transfer a rig to another mesh of the same character: keyed by logical
/// ids only, no vertex, edge or face index crosses from one mesh to the other.

#include "curvenet/compare.hpp"
#include "curvenet/embed.hpp"
#include "curvenet/rig.hpp"
#include "curvenet/surface_mesh.hpp"

#include <optional>
#include <string>
#include <vector>

namespace curvenet {

/// How the source and the target are lined up.
enum class Alignment {
  Frames,    ///< by source_frame and target_frame, as given
  Skeletons, ///< by their skeletons (fit_skeletons), or refused when they do not fit
  /// By their skeletons when both are given, both frames are the identity
  /// (none was given) and the skeletons fit; by the frames otherwise, the
  /// report saying why.
  Auto,
};
const char* to_string(Alignment a);
/// "frames", "skeletons" or "auto". Throws InputError naming `option` otherwise.
Alignment parse_alignment(const std::string& text, const std::string& option);

/// Two skeletons of one character lined up: the similarity (rotation,
/// uniform scale, translation) that carries the source's joints onto the
/// target's, joints matched by name (a least-squares fit, Eigen::umeyama).
struct SkeletonFit {
  Mat4 source_to_target = Mat4::Identity();
  int joints = 0;   ///< matched by name
  double scale = 1; ///< of source_to_target
  double worst = 0; ///< the joint farthest from its match after the fit, as a fraction of `diagonal`
};

/// The fit of two skeletons, each in its own mesh's space (a skinned file's
/// joints, SkinnedMesh::joints), or empty with the reason in `why`: fewer
/// than three joints match by name, the matched joints lie on one line, or
/// a joint lies farther than Tolerances::skeleton_fit_rel * diagonal from
/// its match after the fit (another rig, or a bind pose of its own).
std::optional<SkeletonFit> fit_skeletons(const std::vector<Joint>& source, const std::vector<Joint>& target,
                                         double diagonal, std::string* why = nullptr);

struct TransferOptions {
  /// Maps the source mesh's space to a common world, and the target's too.
  /// The rig's coordinates reach the target through
  /// target_frame^-1 * source_frame * rig.frame.
  Mat4 source_frame = Mat4::Identity();
  Mat4 target_frame = Mat4::Identity();
  /// Or the meshes are lined up by the skeletons their skins carry, each in
  /// its mesh's space: a game LOD exported in other axes or units (Blender's
  /// Y up, an armature's scale of 100) lines up with no frame given.
  Alignment alignment = Alignment::Frames;
  std::vector<Joint> source_skeleton, target_skeleton;
  /// A node or profile point farther than this fraction of the target's
  /// bounding-box diagonal from the target surface is refused.
  double max_offset = 0.05;
  /// When > 0, the target is a Catmull-Clark control cage. A cage is not
  /// the surface it stands for, and closest points or normals from a
  /// surface to a cage fold the net. The rig is placed on the cage's limit
  /// surface (the cage refined this many times) and carried down to the
  /// cage by the refinement's own parameters.
  int target_cage_levels = 0;
  /// The same for a source that is a cage: its rig is carried up to the
  /// limit surface before it is placed on the target.
  int source_cage_levels = 0;
  /// A cage refined past this many faces is refused before it is made.
  long long max_faces = 4'000'000;
  EmbedOptions embed;
};

struct RegionAgreement {
  std::string key;  ///< the region's identity: its (profile, side) pairs
  double area = 0;  ///< on the target
  double agree = 0; ///< fraction of that area whose source region has the same identity
};

struct TransferReport {
  EmbedReport source, target;
  std::vector<RegionAgreement> regions;
  double agreement = 0;       ///< over the whole target area
  double max_node_offset = 0; ///< largest distance a node moved onto the target, as % of its diagonal
  /// How far apart the two surfaces are before anything is placed: the
  /// source mapped into the target's space against the target (percentages
  /// of the mapped source's diagonal); a cage counts by its limit surface. A transfer needs the same shape in
  /// the same pose; a large distance says why one fails.
  SurfaceDistance shape;
  /// How the meshes were lined up: "frames", or "skeletons" with the fit;
  /// with Alignment::Auto and skeletons that do not fit, why not.
  std::string alignment = "frames";
  std::optional<SkeletonFit> skeleton_fit;
  bool ok = false; ///< the target embedding is ok with the same logical counts
  std::vector<std::string> problems;
  /// What the user should know that is not a problem: parts of one mesh
  /// that no curve touches, left out of the comparison.
  std::vector<std::string> notes;
};

struct TransferResult {
  Rig rig; ///< in the target's space (frame = identity), same ids, skeleton and weights
  TransferReport report;
};

/// \throw EmbedError when the rig does not embed on the source, or a node or
///   profile cannot be placed on the target (it lies too far off the surface,
///   or its projection jumps to another part of the surface) or cut into it;
///   the message names it, says why, and says how far apart the surfaces are.
TransferResult transfer(const Rig& rig, const SurfaceMesh& source, const SurfaceMesh& target,
                        const TransferOptions& options = {});

/// The transfer report as JSON text.
std::string transfer_report_json(const TransferReport& report);

} // namespace curvenet
