#pragma once
// The symmetric surface distance (curvenet/compare.hpp) on trace meshes
// already built: the transfer has them for placing, and building them is
// most of the cost on a large mesh.

#include "curvenet/compare.hpp"
#include "trace/trace_mesh.hpp"

namespace curvenet::detail {

/// `ta` and `tb` are the trace meshes of `a` and `b`.
SurfaceDistance surface_distance(const SurfaceMesh& a, const TraceMesh& ta, const SurfaceMesh& b, const TraceMesh& tb,
                                 int samples_per_edge);

} // namespace curvenet::detail
