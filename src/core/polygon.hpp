#pragma once
// Triangulating a polygon in its own plane (ear clipping, exact orientation
// tests). Used for tracing on the input mesh and for the Laplacian of the
// cut mesh.

#include <Eigen/Core>

#include <array>
#include <vector>

namespace curvenet::detail {

/// Triangles (as indices into `corners`) covering a polygon given
/// counter-clockwise. A quad is split along its shorter diagonal (when both
/// splits are valid); a larger polygon by ear clipping, and one that is not
/// planar enough to have a clean ear at some step gets its first corner cut
/// there.
std::vector<std::array<int, 3>> triangulate_polygon(const std::vector<Eigen::Vector3d>& corners);

} // namespace curvenet::detail
