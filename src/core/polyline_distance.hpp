#pragma once
// Distances between polylines in space: how far a traced path strays from
// the curve it follows (the symmetric Hausdorff distance), and how close two
// curves come to each other.

#include <Eigen/Core>

#include <functional>
#include <vector>

namespace curvenet::detail {

/// Distance from p to the segment ab.
double point_segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b);

/// Distance between segments p0-p1 and q0-q1; `on_q` gets the closest point on q.
double segment_distance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& q0,
                        const Eigen::Vector3d& q1, Eigen::Vector3d* on_q = nullptr);

/// A point of a polyline with a key that does not decrease along it (the
/// sample a traced point belongs to).
struct KeyedPoint {
  Eigen::Vector3d pos;
  int key = 0;
  /// Not measured from: this point, and the segment that ends at it. (It is
  /// still a target for the other polyline's points.)
  bool skip = false;
};

/// The largest distance from a point of polyline `from` (its vertices and
/// the midpoints of its segments) to polyline `to`. A point between vertices
/// with keys k0 <= k1 of `from` is measured against the segments of `to`
/// that have an end with a key in [k0 - window, k1 + window]. Restricting the search can only overstate the
/// distance. Also returns which vertex of `from` is farthest (the segment
/// start, for a midpoint).
struct DirectedDistance {
  double distance = 0;
  size_t at = 0;
};
DirectedDistance directed_hausdorff(const std::vector<KeyedPoint>& from, const std::vector<KeyedPoint>& to, int window);

/// Which points of a polyline to keep so that it stays within `tolerance`
/// of the whole (Douglas-Peucker): the two ends always, in order. Given
/// `off_surface` (a point's distance from a surface the polyline lies on),
/// a chord must also stay within `tolerance` of that surface, measured
/// where the points it leaves out come nearest to it: a coarse surface's
/// ridge is not cut across.
std::vector<size_t> simplify_polyline(const std::vector<Eigen::Vector3d>& points, double tolerance,
                                      const std::function<double(const Eigen::Vector3d&)>& off_surface = {});

/// The same between two short polylines, every segment against every other.
double hausdorff(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b);

} // namespace curvenet::detail
