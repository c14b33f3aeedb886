#pragma once
// Exact geometric predicates. Every combinatorial decision in curvenet (which
// side of a plane, which way around a vertex) goes through these, never
// through a tuned epsilon. They wrap CGAL's filtered exact kernel (LGPL).

#include <Eigen/Core>

namespace curvenet::detail {

/// Sign of the orientation of (a, b, c) in the plane: +1 counter-clockwise,
/// -1 clockwise, 0 collinear. Exact for the given doubles.
int orient2d(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c);

/// Sign of the orientation of d against the plane through (a, b, c): +1 when
/// d lies on the side that (b - a) x (c - a) points to, -1 on the other side,
/// 0 on the plane. Exact for the given doubles.
int orient3d(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d);

/// True when the three points are exactly collinear (or coincide).
bool collinear3d(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c);

} // namespace curvenet::detail
