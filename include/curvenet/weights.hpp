#pragma once
/// \file weights.hpp
/// Automatic joint weights for a point, from the nearest bone segment. Used
/// for rig nodes that carry no weights (bind) and by the starter net.

#include "curvenet/rig.hpp"
#include "curvenet/skin.hpp"

#include <utility>
#include <vector>

namespace curvenet {

enum class WeightRule {
  /// The thesis's rule: on the nearest bone (parent p -> child c) at
  /// parameter t, weights {p: 1 - t, c: t}. A node at mid-bone follows the
  /// child joint half-way, so flexing a joint also bends the bone before it.
  Segment,
  /// The nearest bone follows its parent joint rigidly, except in a zone
  /// around each joint where it blends smoothly toward the neighbouring
  /// bone's joint, reaching 1/2 and 1/2 at the joint itself. Past a joint
  /// with no child bone, points follow that joint.
  BlendZone,
};
const char* to_string(WeightRule rule);

struct AutoWeightOptions {
  WeightRule rule = WeightRule::BlendZone;
  /// BlendZone: the zone's half-width on each bone, as a fraction of that
  /// bone's length.
  double blend = 0.3;
};

/// Sparse weights (joint index, weight) for point p, summing to 1, largest
/// first. Bones run from each joint's parent to the joint; a skeleton of
/// one joint gives that joint weight 1.
/// \pre `joints` is not empty and parents come before children.
std::vector<std::pair<int, double>> auto_weights(const std::vector<Joint>& joints, const Eigen::Vector3d& p,
                                                 const AutoWeightOptions& options = {});

/// The same from the nearest of `bones` only (each named by the index of
/// its child joint; all bones when empty): a point on a ring around a limb
/// takes its weights from that limb, never from a bone that merely passes
/// near (a tail hanging beside a thigh, a head lowered to a foreleg).
std::vector<std::pair<int, double>> auto_weights(const std::vector<Joint>& joints, const Eigen::Vector3d& p,
                                                 const AutoWeightOptions& options, const std::vector<int>& bones);

/// Each joint's parent (its index, -1 for a root), by the joints' names.
std::vector<int> joint_parents(const std::vector<Joint>& joints);

/// The same with `parent` = joint_parents(joints), for many points.
std::vector<std::pair<int, double>> auto_weights(const std::vector<Joint>& joints, const std::vector<int>& parent,
                                                 const Eigen::Vector3d& p, const AutoWeightOptions& options,
                                                 const std::vector<int>& bones);

/// How far linear blend skinning with automatic weights lands from the same
/// skinning with a file's own skin weights, over a set of poses (skinning
/// matrices per joint). Distances are in the units of `positions`.
struct SkinComparison {
  double mean = 0;
  double max = 0;
};
SkinComparison compare_with_skin(const SkinnedMesh& skin, const std::vector<Eigen::Vector3d>& positions,
                                 const std::vector<std::vector<Mat4>>& poses, const AutoWeightOptions& options);

} // namespace curvenet
