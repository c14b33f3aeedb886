#pragma once
// The animate job with its binding step handed in: a farm task binds
// through a shared cache behind a lock (farm.cpp).

#include "curvenet/jobs.hpp"

#include <functional>

namespace curvenet::detail {

using Binder = std::function<BoundScene(Scene, OutputFiles&)>;
AnimateSummary run_animate(const AnimateJob& job, const Binder& binder);

} // namespace curvenet::detail
