#pragma once
// Triangulating a polygon in its own plane (ear clipping, exact orientation
// tests), and the closest point of a triangle. Used for tracing on the
// input mesh, for laying out faces of the cut mesh and for its Laplacian.

#include <Eigen/Core>

#include <array>
#include <span>
#include <vector>

namespace curvenet::detail {

/// Triangles (as indices into `corners`) covering a polygon given
/// counter-clockwise. A quad is split along its shorter diagonal (when both
/// splits are valid); a larger polygon by ear clipping, and one that is not
/// planar enough to have a clean ear at some step gets its first corner cut
/// there.
std::vector<std::array<int, 3>> triangulate_polygon(const std::vector<Eigen::Vector3d>& corners);
/// The same, into `tris` (cleared first), for loops over many faces.
void triangulate_polygon(std::span<const Eigen::Vector3d> corners, std::vector<std::array<int, 3>>& tris);

/// Closest point on triangle (a, b, c) to p, with its barycentric
/// coordinates (exact zeros where the point is clamped to a side or corner).
struct TriClosest {
  Eigen::Vector3d point;
  std::array<double, 3> bary;
};
TriClosest closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                               const Eigen::Vector3d& c);

} // namespace curvenet::detail
