#pragma once
// The similarity between two skeletons' rests, shared by the clips' placing
// (pose.cpp) and the note on an armature applied twice (jobs/run.cpp).

#include "curvenet/skin.hpp"

#include <optional>
#include <vector>

namespace curvenet::detail {

/// The similarity (Umeyama, with scale) that best takes the clip file's
/// bind positions to the rig's joints of the same names; none where fewer
/// than three joints match.
std::optional<Mat4> skeleton_similarity(const std::vector<Joint>& rig, const SkinnedMesh& clips);

} // namespace curvenet::detail
