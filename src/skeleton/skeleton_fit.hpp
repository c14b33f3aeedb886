#pragma once
// Two skeletons' rests side by side: their joints matched by name, shared
// by the transfer's skeleton fit (transfer.cpp), and the similarity between
// them, shared by the clips' placing (pose.cpp) and the note on an armature
// applied twice (jobs/run.cpp).

#include "curvenet/skin.hpp"

#include <optional>
#include <utility>
#include <vector>

namespace curvenet::detail {

/// The bind positions of the joints of `by` that `other` has too (by name),
/// in `by`'s order, and those of their matches in `other`: a column each.
std::pair<Eigen::Matrix3Xd, Eigen::Matrix3Xd> matched_bind_positions(const std::vector<Joint>& by,
                                                                     const std::vector<Joint>& other);

/// The similarity (Umeyama, with scale) that best takes the clip file's
/// bind positions to the rig's joints of the same names; none where fewer
/// than three joints match.
std::optional<Mat4> skeleton_similarity(const std::vector<Joint>& rig, const SkinnedMesh& clips);

} // namespace curvenet::detail
