#pragma once
// The animate job with its binding step handed in: a farm task binds
// through a shared cache behind a lock (farm.cpp); and the clip lookup
// both use.

#include "curvenet/jobs.hpp"

#include <functional>

namespace curvenet::detail {

using Binder = std::function<BoundScene(Scene, OutputFiles&)>;
AnimateSummary run_animate(const AnimateJob& job, const Binder& binder);

/// Refuses a clip file with no clips (`why` ends the message: " to carry").
void need_clips(const SkinnedMesh& clips, const std::string& file, const std::string& why = "");
/// The clip file's clip `name` (a name or an index; the first when empty),
/// or a refusal naming the file.
int find_clip(const SkinnedMesh& clips, const std::string& file, const std::string& name);

} // namespace curvenet::detail
